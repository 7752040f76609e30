//! Deterministic sample sequences and warps.
//!
//! Every random number in a bake is a pure function of (what is being sampled — texel, path,
//! light —, the sample number, the dimension and [`crate::settings::BakeSettings::seed`]),
//! never of the thread that computes it, so a bake gives the same bits on any thread count.
//!
//! * [`Fnv1a`]: the FNV-1a hash of a byte stream (Fowler, Noll and Vo), for identifying
//!   content (a split bake's scene and preparation), not for sampling.
//! * [`hash`]: an integer mixer (the "lowbias32" finaliser of Chris Wellons' hash prospector)
//!   to derive independent scrambles.
//! * [`radical_inverse`] / [`halton`]: the Halton sequence Φ_b(i) with prime bases
//!   (Halton 1960; Keller 1997 uses it for instant radiosity).
//! * [`sobol_02`]: the first two Sobol' dimensions, a (0,2)-sequence in base 2, with Owen
//!   scrambling by the Laine–Karras hash (Burley 2020, "Practical Hash-based Owen
//!   Scrambling"): every power-of-two prefix is stratified in both dimensions jointly.
//! * Warps: cosine hemisphere (Malley's method), cone, triangle, disc, and an orthonormal
//!   basis (Duff et al. 2017).

use glam::{Vec2, Vec3};

/// The 64-bit FNV-1a hash of the bytes fed to it.
#[derive(Clone, Copy, Debug)]
pub struct Fnv1a(u64);

impl Default for Fnv1a {
    fn default() -> Self {
        Self(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv1a {
    /// Feeds `bytes`.
    pub fn bytes(&mut self, bytes: &[u8]) {
        for b in bytes {
            self.0 ^= *b as u64;
            self.0 = self.0.wrapping_mul(0x0100_0000_01b3);
        }
    }

    /// Feeds a 32-bit word, little-endian.
    pub fn word(&mut self, w: u32) {
        self.bytes(&w.to_le_bytes());
    }

    /// The hash so far.
    pub fn finish(&self) -> u64 {
        self.0
    }
}

/// Mixes a 32-bit value ("lowbias32", bias ≈ 0.17).
#[inline]
pub fn hash(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

/// Hashes several words into one (order matters).
#[inline]
pub fn hash_words(words: &[u32]) -> u32 {
    words.iter().fold(0x9e37_79b9u32, |h, &w| {
        hash(h ^ w.wrapping_add(0x632b_e5ab))
    })
}

/// Maps 32 random bits to [0, 1) (24-bit mantissa, never 1.0).
#[inline]
pub fn unit_float(bits: u32) -> f32 {
    (bits >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
}

/// The first 64 primes: the Halton bases for dimensions 0..64.
pub const PRIMES: [u32; 64] = [
    2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37, 41, 43, 47, 53, 59, 61, 67, 71, 73, 79, 83, 89, 97,
    101, 103, 107, 109, 113, 127, 131, 137, 139, 149, 151, 157, 163, 167, 173, 179, 181, 191, 193,
    197, 199, 211, 223, 227, 229, 233, 239, 241, 251, 257, 263, 269, 271, 277, 281, 283, 293, 307,
    311,
];

/// The radical inverse Φ_b(i): the digits of `i` in base `b` mirrored about the radix point.
#[inline]
pub fn radical_inverse(base: u32, mut i: u64) -> f64 {
    let inv_base = 1.0 / base as f64;
    let mut inv = inv_base;
    let mut result = 0.0;
    while i > 0 {
        let digit = i % base as u64;
        result += digit as f64 * inv;
        i /= base as u64;
        inv *= inv_base;
    }
    result
}

/// Component `dim` (< 64) of the `i`-th Halton point (base `PRIMES[dim]`).
///
/// # Panics
/// If `dim >= 64`.
#[inline]
pub fn halton(dim: usize, i: u64) -> f64 {
    radical_inverse(PRIMES[dim], i)
}

/// Radical inverse with random digit scrambling: digit k of `i` in base `base` becomes
/// (digit + s_k) mod base, s_k a hash of (`seed`, k). Keeps the stratification of Φ_b
/// (each digit position still runs through every value) while decorrelating repeated use.
#[inline]
pub fn scrambled_radical_inverse(base: u32, mut i: u64, seed: u32) -> f64 {
    let inv_base = 1.0 / base as f64;
    let mut inv = inv_base;
    let mut result = 0.0;
    let mut k = 0u32;
    // Enough digits for double precision (or until the remaining digits are all zero and
    // their scrambled values vanish below f64 resolution).
    while inv > 1e-15 {
        let digit = (i % base as u64) as u32;
        let shifted = (digit + hash_words(&[seed, k]) % base) % base;
        result += shifted as f64 * inv;
        i /= base as u64;
        inv *= inv_base;
        k += 1;
    }
    result.min(1.0 - f64::EPSILON)
}

/// A bijection of [0, n) chosen by `seed` (a hash applied by cycle-walking within the next
/// power of two), to shuffle strata.
pub fn permute(i: u32, n: u32, seed: u32) -> u32 {
    debug_assert!(i < n);
    let bits = 32 - (n.max(2) - 1).leading_zeros();
    let mask = if bits >= 32 {
        u32::MAX
    } else {
        (1u32 << bits) - 1
    };
    let mut x = i;
    loop {
        // An invertible mix on `bits` bits: xorshift and odd multiplies, masked.
        x ^= seed & mask;
        x = x.wrapping_mul(0x9e37_79b1 | 1) & mask;
        x ^= (x >> (bits / 2).max(1)) & mask;
        x = x.wrapping_mul(0x85eb_ca6b | 1) & mask;
        x ^= (x >> (bits / 2).max(1)) & mask;
        if x < n {
            return x;
        }
    }
}

/// Which numbers drive a quasi-random walk, per Keller's comparison of random, jittered and
/// Halton patterns.
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Sequence {
    /// The Halton sequence: dimension d of point i is Φ_{p_d}(i + 1).
    #[default]
    Halton,
    /// Halton with random digit scrambling per dimension (seeded).
    ScrambledHalton,
    /// Jittered (stratified) per dimension: ((π_d(i) + ξ)/N), π_d a seeded permutation, as a
    /// Latin hypercube.
    Jittered,
    /// Independent uniform random numbers (hashed from index, dimension and seed).
    Random,
}

impl Sequence {
    /// Component `dim` (< 64) of point `i` of an `n`-point set.
    pub fn sample(self, i: u32, n: u32, dim: usize, seed: u32) -> f32 {
        let v = match self {
            Sequence::Halton => halton(dim, i as u64 + 1),
            Sequence::ScrambledHalton => scrambled_radical_inverse(
                PRIMES[dim],
                i as u64 + 1,
                hash_words(&[seed, dim as u32]),
            ),
            Sequence::Jittered => {
                let stratum = permute(i, n.max(1), hash_words(&[seed, dim as u32, 0x717]));
                let xi = unit_float(hash_words(&[seed, dim as u32, i])) as f64;
                (stratum as f64 + xi) / n.max(1) as f64
            }
            Sequence::Random => unit_float(hash_words(&[seed, dim as u32, i, 0xabc])) as f64,
        };
        (v as f32).min(1.0 - f32::EPSILON)
    }
}

/// Reverses the bits of a 32-bit word.
#[inline]
fn reverse_bits(x: u32) -> u32 {
    x.reverse_bits()
}

/// Laine–Karras hash: an Owen scramble of a bit-reversed integer (Burley 2020, listing 2,
/// with the improved constants).
#[inline]
fn laine_karras_permutation(mut x: u32, seed: u32) -> u32 {
    x ^= x.wrapping_mul(0x3d20_adea);
    x = x.wrapping_add(seed);
    x = x.wrapping_mul((seed >> 16) | 1);
    x ^= x.wrapping_mul(0x0552_6c56);
    x ^= x.wrapping_mul(0x53a2_2864);
    x
}

/// Nested uniform (Owen) scramble of a 32-bit binary fraction.
#[inline]
fn nested_uniform_scramble(x: u32, seed: u32) -> u32 {
    reverse_bits(laine_karras_permutation(reverse_bits(x), seed))
}

/// Sobol' dimension 1 as a 32-bit fraction (generator matrix: Pascal's triangle mod 2): the
/// XOR of the generator columns of the set bits of `index`, a byte at a time from
/// [`SOBOL_DIM1_TABLES`] (the indices here are scrambled, so all 32 bits are in play).
#[inline]
fn sobol_dim1(index: u32) -> u32 {
    let t = &SOBOL_DIM1_TABLES;
    t[0][(index & 0xff) as usize]
        ^ t[1][((index >> 8) & 0xff) as usize]
        ^ t[2][((index >> 16) & 0xff) as usize]
        ^ t[3][(index >> 24) as usize]
}

/// Bit by bit: the definition [`sobol_dim1`]'s tables are built from (and tested against).
const fn sobol_dim1_bitwise(mut index: u32) -> u32 {
    let mut v: u32 = 1 << 31;
    let mut result = 0u32;
    while index != 0 {
        if index & 1 != 0 {
            result ^= v;
        }
        index >>= 1;
        v ^= v >> 1;
    }
    result
}

/// `SOBOL_DIM1_TABLES[k][b]` = Sobol' dimension 1 of the index `b << 8k`.
static SOBOL_DIM1_TABLES: [[u32; 256]; 4] = {
    let mut t = [[0u32; 256]; 4];
    let mut k = 0;
    while k < 4 {
        let mut b = 0;
        while b < 256 {
            t[k][b] = sobol_dim1_bitwise((b as u32) << (8 * k));
            b += 1;
        }
        k += 1;
    }
    t
};

/// Point `i` of an Owen-scrambled (0,2)-sequence, decorrelated by `seed`. Each prefix of 2^k
/// points has exactly one point in every elementary interval of area 2^-k.
#[inline]
pub fn sobol_02(i: u32, seed: u32) -> Vec2 {
    Sobol02::new(seed).point(i)
}

/// The sequence of [`sobol_02`] for one seed, with the seed's hashes done once (for loops over
/// many points of one seed).
#[derive(Clone, Copy, Debug)]
pub struct Sobol02 {
    shuffle: u32,
    x: u32,
    y: u32,
}

impl Sobol02 {
    /// The sequence decorrelated by `seed`.
    #[inline]
    pub fn new(seed: u32) -> Self {
        Self {
            shuffle: hash(seed ^ 0xa511_e9b3),
            x: hash(seed ^ 0x63d8_3595),
            y: hash(seed ^ 0x2c1b_3c6d),
        }
    }

    /// Point `i` (equal to `sobol_02(i, seed)`).
    #[inline]
    pub fn point(&self, i: u32) -> Vec2 {
        // Shuffle the order (Owen-scramble the index) so different seeds give different subsets.
        let index = nested_uniform_scramble(i, self.shuffle);
        let x = index.reverse_bits(); // van der Corput = Sobol' dimension 0
        let y = sobol_dim1(index);
        let sx = nested_uniform_scramble(x, self.x);
        let sy = nested_uniform_scramble(y, self.y);
        Vec2::new(unit_float(sx), unit_float(sy))
    }
}

/// Builds a right-handed orthonormal basis (t, b, n) around unit `n` (Duff et al. 2017,
/// "Building an Orthonormal Basis, Revisited").
#[inline]
pub fn basis(n: Vec3) -> (Vec3, Vec3) {
    let sign = 1.0f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        Vec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

/// Cosine-distributed direction about unit `n` (pdf cosθ/π), by Malley's method with the
/// concentric disc map (Shirley & Chiu 1997).
#[inline]
pub fn cosine_hemisphere(n: Vec3, u: Vec2) -> Vec3 {
    let d = concentric_disc(u);
    let z = (1.0 - d.length_squared()).max(0.0).sqrt();
    let (t, b) = basis(n);
    (t * d.x + b * d.y + n * z).normalize()
}

/// Maps the unit square to the unit disc, preserving stratification (Shirley & Chiu 1997).
#[inline]
pub fn concentric_disc(u: Vec2) -> Vec2 {
    let o = 2.0 * u - Vec2::ONE;
    if o.x == 0.0 && o.y == 0.0 {
        return Vec2::ZERO;
    }
    // The angle is π/4·(y/x) in the left and right wedges and π/2 − π/4·(x/y) in the top and
    // bottom ones: both within a quarter turn, where [`sin_cos_quarter`] holds.
    let q = std::f32::consts::FRAC_PI_4;
    if o.x.abs() > o.y.abs() {
        let (s, c) = sin_cos_quarter(q * (o.y / o.x));
        o.x * Vec2::new(c, s)
    } else {
        let (s, c) = sin_cos_quarter(q * (o.x / o.y));
        o.y * Vec2::new(s, c)
    }
}

/// (sin a, cos a) for |a| ≤ π/4, to within 2.5·10⁻⁷ of the standard library's: short
/// polynomials in place of `sincosf`, which is called once per cosine-weighted transport
/// direction and is a visible share of a bake's profile. sin a = a + a³·S(a²) and cos a = 1 − a²/2 +
/// a⁴·C(a²) with S and C cubics fitted (least squares at 400 Chebyshev nodes, weighted for
/// relative error, against 40-digit references) on [0, π²/16]: their relative error is below
/// 2·10⁻¹⁰, far under f32 rounding.
#[inline]
fn sin_cos_quarter(a: f32) -> (f32, f32) {
    const S: [f32; 4] = [
        -0.166_666_67,
        0.008_333_332,
        -0.000_198_400_82,
        2.724_937_3e-6,
    ];
    const C: [f32; 4] = [
        0.041_666_668,
        -0.001_388_888_8,
        2.480_059_8e-5,
        -2.730_066e-7,
    ];
    debug_assert!(a.abs() <= std::f32::consts::FRAC_PI_4 * 1.0001, "{a}");
    let z = a * a;
    // Horner's rule with plain multiply-adds (`mul_add` is a library call without the `fma`
    // target feature).
    let horner = |c: &[f32; 4]| c.iter().rev().fold(0.0, |acc, &k| acc * z + k);
    (a + a * z * horner(&S), 1.0 - 0.5 * z + z * z * horner(&C))
}

/// Uniform direction in the cone of half-angle acos(`cos_max`) about unit `axis`.
#[inline]
pub fn uniform_cone(axis: Vec3, cos_max: f32, u: Vec2) -> Vec3 {
    let cos_theta = 1.0 - u.x * (1.0 - cos_max);
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let phi = std::f32::consts::TAU * u.y;
    let (t, b) = basis(axis);
    (t * (sin_theta * phi.cos()) + b * (sin_theta * phi.sin()) + axis * cos_theta).normalize()
}

/// Uniform barycentric coordinates (b1, b2) on a triangle; the point is
/// `(1 − b1 − b2)·p0 + b1·p1 + b2·p2`. Uses the square-root parameterisation, which keeps
/// stratification.
#[inline]
pub fn uniform_triangle(u: Vec2) -> Vec2 {
    let s = u.x.sqrt();
    Vec2::new(s * (1.0 - u.y), s * u.y)
}

/// A direction towards a triangle, drawn uniformly in the solid angle it subtends at `o`
/// (Arvo, "Stratified sampling of spherical triangles", SIGGRAPH 1995, fig. 2). Returns the
/// unit direction and the solid angle Ω (sr); the density is 1/Ω. `None` when the triangle
/// is degenerate as seen from `o` or subtends too little for the angles to be accurate
/// (Ω < `min_solid_angle`): callers then sample by area.
pub fn spherical_triangle(
    o: Vec3,
    v: [Vec3; 3],
    u: Vec2,
    min_solid_angle: f32,
) -> Option<(Vec3, f32)> {
    let [a, b, c] = v.map(|p| (p - o).as_dvec3().normalize_or_zero());
    if a == glam::DVec3::ZERO || b == glam::DVec3::ZERO || c == glam::DVec3::ZERO {
        return None;
    }
    // Solid angle (Van Oosterom & Strackee 1983): tan(Ω/2) = |a·(b×c)| / (1 + a·b + b·c + c·a).
    let triple = a.dot(b.cross(c)).abs();
    let omega = 2.0 * triple.atan2(1.0 + a.dot(b) + b.dot(c) + c.dot(a));
    if omega.is_nan() || omega < min_solid_angle as f64 {
        return None;
    }
    // Interior angle α at a, from the normals of the great circles a–b and a–c: its cosine
    // and sine directly (no acos), since only they and sin/cos(Â − α) are needed.
    let (n1, n2) = (
        a.cross(b).normalize_or_zero(),
        a.cross(c).normalize_or_zero(),
    );
    let cos_alpha = n1.dot(n2).clamp(-1.0, 1.0);
    let sin_alpha = n1.cross(n2).length().min(1.0);
    let cos_c = a.dot(b);
    // 1. Pick the sub-triangle area Â = u₀·Ω and find its third vertex ĉ on the arc from a to c.
    let (sin_area, cos_area) = (u.x as f64 * omega).sin_cos();
    // sin and cos of Â − α.
    let s = sin_area * cos_alpha - cos_area * sin_alpha;
    let t = cos_area * cos_alpha + sin_area * sin_alpha;
    let uu = t - cos_alpha;
    let vv = s + sin_alpha * cos_c;
    let q =
        (((vv * t - uu * s) * cos_alpha - vv) / ((vv * s + uu * t) * sin_alpha)).clamp(-1.0, 1.0);
    let c_perp = (c - c.dot(a) * a).normalize_or_zero();
    let c_hat = q * a + (1.0 - q * q).max(0.0).sqrt() * c_perp;
    // 2. Pick a point on the arc from b to ĉ with the right density.
    let z = 1.0 - u.y as f64 * (1.0 - c_hat.dot(b));
    let ch_perp = (c_hat - c_hat.dot(b) * b).normalize_or_zero();
    let dir = z * b + (1.0 - z * z).max(0.0).sqrt() * ch_perp;
    let dir = dir.normalize_or_zero().as_vec3();
    (dir != Vec3::ZERO && dir.is_finite()).then_some((dir, omega as f32))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quarter_sin_cos_matches_the_standard_library() {
        let q = std::f32::consts::FRAC_PI_4;
        let mut worst = 0.0f32;
        for i in 0..=100_000 {
            let a = -q + 2.0 * q * i as f32 / 100_000.0;
            let (s, c) = sin_cos_quarter(a);
            worst = worst.max((s - a.sin()).abs()).max((c - a.cos()).abs());
        }
        assert!(worst < 2.5e-7, "{worst}");
        assert_eq!(sin_cos_quarter(0.0), (0.0, 1.0));
    }

    /// The polynomial sine and cosine give the disc the standard library's angles.
    #[test]
    fn concentric_disc_matches_its_trigonometric_definition() {
        use std::f32::consts::{FRAC_PI_2, FRAC_PI_4};
        let mut worst = 0.0f32;
        for i in 0..=256 {
            for j in 0..=256 {
                let u = Vec2::new(i as f32, j as f32) / 256.0;
                let o = 2.0 * u - Vec2::ONE;
                let expected = if o == Vec2::ZERO {
                    Vec2::ZERO
                } else if o.x.abs() > o.y.abs() {
                    let t = FRAC_PI_4 * (o.y / o.x);
                    o.x * Vec2::new(t.cos(), t.sin())
                } else {
                    let t = FRAC_PI_2 - FRAC_PI_4 * (o.x / o.y);
                    o.y * Vec2::new(t.cos(), t.sin())
                };
                worst = worst.max((concentric_disc(u) - expected).abs().max_element());
            }
        }
        assert!(worst < 3e-7, "{worst}");
    }

    #[test]
    fn table_sobol_matches_the_bitwise_definition() {
        for i in (0..100_000u32).chain([u32::MAX, 1 << 31, 0xdead_beef]) {
            let x = hash(i);
            assert_eq!(sobol_dim1(x), sobol_dim1_bitwise(x), "index {x:#x}");
            assert_eq!(sobol_dim1(i), sobol_dim1_bitwise(i));
        }
    }

    #[test]
    fn radical_inverse_known_values() {
        assert_eq!(radical_inverse(2, 1), 0.5);
        assert_eq!(radical_inverse(2, 2), 0.25);
        assert_eq!(radical_inverse(2, 3), 0.75);
        assert!((radical_inverse(3, 1) - 1.0 / 3.0).abs() < 1e-15);
        assert!((radical_inverse(3, 5) - (2.0 / 3.0 + 1.0 / 9.0)).abs() < 1e-15);
        assert!((halton(1, 4) - radical_inverse(3, 4)).abs() < 1e-15);
    }

    #[test]
    fn permutations_are_bijections() {
        for n in [1u32, 2, 7, 64, 1000] {
            let mut seen = vec![false; n as usize];
            for i in 0..n {
                let j = permute(i, n, 42) as usize;
                assert!(!seen[j]);
                seen[j] = true;
            }
        }
    }

    #[test]
    fn sequences_are_in_range_and_halton_is_stratified() {
        for seq in [
            Sequence::Halton,
            Sequence::ScrambledHalton,
            Sequence::Jittered,
            Sequence::Random,
        ] {
            for i in 0..512 {
                for d in 0..8 {
                    let v = seq.sample(i, 512, d, 9);
                    assert!((0.0..1.0).contains(&v), "{seq:?} {v}");
                }
            }
        }
        // The first 3^4 points of Φ_3 fall one in each of 81 strata, scrambled or not.
        let mut seen = [0u32; 81];
        for i in 0..81u64 {
            seen[(radical_inverse(3, i) * 81.0 + 1e-9) as usize] += 1;
        }
        assert!(seen.iter().all(|&c| c == 1));
        let mut seen = [0u32; 81];
        for i in 0..81u64 {
            seen[(scrambled_radical_inverse(3, i, 5) * 81.0 + 1e-9) as usize] += 1;
        }
        assert!(seen.iter().all(|&c| c == 1), "{seen:?}");
        let mut seen = [0u32; 81];
        for i in 0..81 {
            seen[(Sequence::Jittered.sample(i, 81, 2, 3) * 81.0) as usize] += 1;
        }
        assert!(seen.iter().all(|&c| c == 1));
    }

    #[test]
    fn sobol_prefixes_are_stratified() {
        // For 2^k points, every elementary interval of size 2^-a × 2^-(k-a) holds one point.
        for seed in [0u32, 7, 12345] {
            let k = 6u32;
            let n = 1u32 << k;
            let pts: Vec<Vec2> = (0..n).map(|i| sobol_02(i, seed)).collect();
            for a in 0..=k {
                let (nx, ny) = (1u32 << a, 1u32 << (k - a));
                let mut seen = vec![0u32; n as usize];
                for p in &pts {
                    let cx = (p.x * nx as f32) as u32;
                    let cy = (p.y * ny as f32) as u32;
                    seen[(cy * nx + cx) as usize] += 1;
                }
                assert!(seen.iter().all(|&c| c == 1), "seed {seed} a {a}");
            }
        }
    }

    #[test]
    fn sobol_seeds_decorrelate() {
        let a: Vec<Vec2> = (0..16).map(|i| sobol_02(i, 1)).collect();
        let b: Vec<Vec2> = (0..16).map(|i| sobol_02(i, 2)).collect();
        assert_ne!(a, b);
    }

    #[test]
    fn cosine_hemisphere_mean_matches_pdf() {
        // E[cosθ] under pdf cosθ/π is 2/3.
        let n = Vec3::new(0.3, 0.4, 0.866).normalize();
        let count = 4096;
        let mean: f32 = (0..count)
            .map(|i| cosine_hemisphere(n, sobol_02(i, 3)).dot(n))
            .sum::<f32>()
            / count as f32;
        assert!((mean - 2.0 / 3.0).abs() < 2e-3, "{mean}");
        for i in 0..256 {
            let d = cosine_hemisphere(n, sobol_02(i, 9));
            assert!(d.dot(n) >= -1e-6 && (d.length() - 1.0).abs() < 1e-5);
        }
    }

    #[test]
    fn basis_is_orthonormal() {
        for n in [
            Vec3::Z,
            Vec3::NEG_Z,
            Vec3::X,
            Vec3::new(1.0, -2.0, 0.5).normalize(),
        ] {
            let (t, b) = basis(n);
            assert!(t.dot(b).abs() < 1e-6 && t.dot(n).abs() < 1e-6 && b.dot(n).abs() < 1e-6);
            assert!((t.cross(b) - n).length() < 1e-5);
        }
    }

    #[test]
    fn cone_and_triangle_warps_stay_inside() {
        let axis = Vec3::new(0.0, -1.0, 0.0);
        for i in 0..256 {
            let u = sobol_02(i, 5);
            assert!(uniform_cone(axis, 0.99, u).dot(axis) >= 0.99 - 1e-5);
            let b = uniform_triangle(u);
            assert!(b.x >= 0.0 && b.y >= 0.0 && b.x + b.y <= 1.0 + 1e-6);
        }
    }

    #[test]
    fn spherical_triangle_samples_hit_the_triangle_and_integrate_its_form_factor() {
        // A triangle just above the point and off to one side (the near field where area
        // sampling is noisy), and a far one.
        for (o, tri) in [
            (
                Vec3::ZERO,
                [
                    Vec3::new(-0.5, 0.05, -0.5),
                    Vec3::new(2.0, 0.05, 0.0),
                    Vec3::new(0.0, 0.3, 2.0),
                ],
            ),
            (
                Vec3::new(0.1, 0.0, 0.2),
                [
                    Vec3::new(1.0, 3.0, 0.0),
                    Vec3::new(0.0, 3.0, 1.0),
                    Vec3::new(1.0, 3.5, 1.0),
                ],
            ),
        ] {
            let n = 65_536;
            let mut sum = 0.0f64;
            for i in 0..n {
                let (d, omega) = spherical_triangle(o, tri, sobol_02(i, 9), 0.0).unwrap();
                // The direction meets the triangle (Möller–Trumbore with a small tolerance).
                let (e1, e2) = (tri[1] - tri[0], tri[2] - tri[0]);
                let p = d.cross(e2);
                let det = e1.dot(p);
                let s = o - tri[0];
                let (bu, bv) = (s.dot(p) / det, d.dot(s.cross(e1)) / det);
                assert!(
                    bu > -1e-3 && bv > -1e-3 && bu + bv < 1.0 + 1e-3,
                    "sample {i} misses: {bu} {bv}"
                );
                sum += (d.y.max(0.0) * omega) as f64;
            }
            let estimate = sum / n as f64 / std::f64::consts::PI;
            let exact = crate::form_factor::point_to_polygon_form_factor(o, Vec3::Y, &tri) as f64;
            assert!(
                (estimate - exact).abs() < 2e-3 * exact.max(1e-3),
                "form factor {estimate} against {exact}"
            );
        }
    }
}
