//! Lightmap pages: patch values written into their texels, invalid texels filled from their
//! chart neighbours, and the padding dilated so bilinear and bicubic sampling never read an
//! unset texel.
//!
//! # What a texel stores
//! Irradiance over π, E/π, in Bevy's light units (lux/π), linear RGB. Bevy's PBR shader adds
//! `lightmap × lightmap_exposure × diffuse_color` (`pbr_functions.wgsl`), and a Lambertian
//! surface of albedo ρ under irradiance E reflects radiance ρ·E/π; so with
//! `lightmap_exposure = 1` the game shows exactly the baked light. A white floor 1 m under a
//! 1 cd point light stores 1/π ≈ 0.318.

pub mod contacts;
pub mod denoise;
// The bake's own check of its texel grid: its signature takes the stages' internal types.
#[cfg(feature = "internals")]
pub mod grid_error;
#[cfg(not(feature = "internals"))]
pub(crate) mod grid_error;
pub mod least_squares;
pub mod seams;
pub mod stitch;

use glam::Vec3;

use crate::raster::Patches;
use crate::unwrap::Layout;

/// Largest finite half-float value: every output format, and Bevy's `Rgba16Float` images,
/// clamp texels to it.
pub const HALF_MAX: f32 = 65504.0;

/// The four texels and weights of a bilinear sample at `uv` of a `width` × `height` image
/// (texel centres at (i + ½)/W, Bevy's and the GPU's convention), clamped at the edges:
/// ((x, y), weight) in the order top-left, top-right, bottom-left, bottom-right.
pub fn bilinear_taps(width: u32, height: u32, u: f32, v: f32) -> [((u32, u32), f32); 4] {
    let x = u * width as f32 - 0.5;
    let y = v * height as f32 - 0.5;
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let clamp = |i: f32, n: u32| (i.max(0.0) as u32).min(n - 1);
    let (xa, xb) = (clamp(x0, width), clamp(x0 + 1.0, width));
    let (ya, yb) = (clamp(y0, height), clamp(y0 + 1.0, height));
    [
        ((xa, ya), (1.0 - fx) * (1.0 - fy)),
        ((xb, ya), fx * (1.0 - fy)),
        ((xa, yb), (1.0 - fx) * fy),
        ((xb, yb), fx * fy),
    ]
}

/// One atlas page of lightmap texels.
#[derive(Clone, Debug, PartialEq)]
pub struct LightmapPage {
    /// Texels across.
    pub width: u32,
    /// Texels down.
    pub height: u32,
    /// E/π per texel, row-major from the top, linear RGB.
    pub texels: Vec<Vec3>,
    /// Texels that belong to a surface (before dilation).
    pub covered: Vec<bool>,
}

impl LightmapPage {
    /// A black page.
    pub fn black(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            texels: vec![Vec3::ZERO; (width * height) as usize],
            covered: vec![false; (width * height) as usize],
        }
    }

    /// The texel at (x, y).
    pub fn get(&self, x: u32, y: u32) -> Vec3 {
        self.texels[(y * self.width + x) as usize]
    }

    /// Bilinear sample at page uv ([`bilinear_taps`]): what the GPU shows.
    pub fn sample_bilinear(&self, u: f32, v: f32) -> Vec3 {
        bilinear_taps(self.width, self.height, u, v)
            .iter()
            .map(|&((x, y), w)| self.get(x, y) * w)
            .sum()
    }

    /// Texel channels above [`HALF_MAX`] (clamped in every output).
    pub fn channels_over_half(&self) -> usize {
        self.texels
            .iter()
            .map(|t| t.to_array().iter().filter(|&&c| c > HALF_MAX).count())
            .sum()
    }
}

/// Statistics of assembling pages.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AssembleStats {
    /// Invalid texels filled from their chart neighbours.
    pub filled: usize,
    /// Invalid texels left black (their chart had no valid texel).
    pub unfilled: usize,
    /// Padding texels set by dilation.
    pub dilated: usize,
}

/// What a page texel holds while the pages are assembled.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TexelState {
    /// No surface: padding, set by dilation (or by a step that solves for it).
    Empty,
    /// An invalid patch (hidden), to be filled from its chart.
    Hidden,
    /// Holds its value.
    Set,
}

/// Pages being assembled: the texels and what each holds. The steps run in order:
/// [`Assembly::new`] writes the valid patches, [`Assembly::fill_hidden`] the invalid ones,
/// later steps adjust values (and may set padding texels they solve for, [`Assembly::set`]),
/// and [`Assembly::dilate`] fills the padding that is left.
#[derive(Clone, Debug)]
pub struct Assembly {
    /// The pages (E/π).
    pub pages: Vec<LightmapPage>,
    /// Per page, per texel.
    pub state: Vec<Vec<TexelState>>,
    /// Counts of the steps so far.
    pub stats: AssembleStats,
}

impl Assembly {
    /// Writes E/π of every valid patch into its page (`irradiance` per patch, lux).
    pub fn new(layout: &Layout, patches: &Patches, irradiance: &[Vec3]) -> Self {
        let mut pages: Vec<LightmapPage> = layout
            .pages
            .iter()
            .map(|p| LightmapPage::black(p.width, p.height))
            .collect();
        let mut state: Vec<Vec<TexelState>> = pages
            .iter()
            .map(|p| vec![TexelState::Empty; p.texels.len()])
            .collect();
        for (i, p) in patches.patches.iter().enumerate() {
            let page = &mut pages[p.page as usize];
            let k = (p.y * page.width + p.x) as usize;
            page.covered[k] = true;
            if p.is_valid() {
                page.texels[k] = irradiance[i] / std::f32::consts::PI;
                state[p.page as usize][k] = TexelState::Set;
            } else {
                state[p.page as usize][k] = TexelState::Hidden;
            }
        }
        Self {
            pages,
            state,
            stats: AssembleStats::default(),
        }
    }

    /// Fills the invalid texels from set neighbours of the same instance and chart, in waves;
    /// those of a chart with no valid texel stay black.
    pub fn fill_hidden(&mut self, patches: &Patches) {
        for (pi, page) in self.pages.iter_mut().enumerate() {
            let index = &patches.page_index[pi];
            let st = &mut self.state[pi];
            loop {
                let mut updates = Vec::new();
                for k in 0..st.len() {
                    if st[k] != TexelState::Hidden {
                        continue;
                    }
                    let me = &patches.patches[index[k] as usize];
                    let (sum, n) = neighbours(page.width, page.height, k, |j| {
                        if st[j] != TexelState::Set || index[j] == u32::MAX {
                            return false;
                        }
                        let other = &patches.patches[index[j] as usize];
                        other.instance == me.instance && other.chart == me.chart
                    })
                    .fold((Vec3::ZERO, 0u32), |(s, n), j| (s + page.texels[j], n + 1));
                    if n > 0 {
                        updates.push((k, sum / n as f32));
                    }
                }
                if updates.is_empty() {
                    break;
                }
                self.stats.filled += updates.len();
                for (k, v) in updates {
                    page.texels[k] = v;
                    st[k] = TexelState::Set;
                }
            }
            for s in st.iter_mut() {
                if *s == TexelState::Hidden {
                    self.stats.unfilled += 1;
                    *s = TexelState::Set; // left black, but set so dilation does not overwrite it
                }
            }
        }
    }

    /// Sets texel `k` of page `page` to `value` (a step that solves for padding texels marks
    /// them set, so dilation keeps them).
    pub fn set(&mut self, page: usize, k: usize, value: Vec3) {
        self.pages[page].texels[k] = value;
        self.state[page][k] = TexelState::Set;
    }

    /// Dilates `passes` texels into the empty space around every chart.
    pub fn dilate(&mut self, passes: u32) {
        for (page, st) in self.pages.iter_mut().zip(&mut self.state) {
            for _ in 0..passes {
                let mut updates = Vec::new();
                for k in 0..st.len() {
                    if st[k] != TexelState::Empty {
                        continue;
                    }
                    let (sum, n) =
                        neighbours(page.width, page.height, k, |j| st[j] == TexelState::Set)
                            .fold((Vec3::ZERO, 0u32), |(s, n), j| (s + page.texels[j], n + 1));
                    if n > 0 {
                        updates.push((k, sum / n as f32));
                    }
                }
                if updates.is_empty() {
                    break;
                }
                self.stats.dilated += updates.len();
                for (k, v) in updates {
                    page.texels[k] = v;
                    st[k] = TexelState::Set;
                }
            }
        }
    }
}

/// Writes E/π of every valid patch into its page, fills the invalid ones from valid
/// neighbours of the same instance and chart, then dilates `dilate_passes` texels into the
/// empty space around every chart (the steps of [`Assembly`] with nothing in between).
pub fn assemble(
    layout: &Layout,
    patches: &Patches,
    irradiance: &[Vec3],
    dilate_passes: u32,
) -> (Vec<LightmapPage>, AssembleStats) {
    let mut a = Assembly::new(layout, patches, irradiance);
    a.fill_hidden(patches);
    a.dilate(dilate_passes);
    (a.pages, a.stats)
}

/// The 8-neighbours of texel `k` accepted by `keep`.
fn neighbours(
    width: u32,
    height: u32,
    k: usize,
    keep: impl Fn(usize) -> bool,
) -> impl Iterator<Item = usize> {
    let (x, y) = ((k as u32 % width) as i64, (k as u32 / width) as i64);
    let (w, h) = (width as i64, height as i64);
    (-1i64..=1)
        .flat_map(move |dy| (-1i64..=1).map(move |dx| (dx, dy)))
        .filter(|&(dx, dy)| dx != 0 || dy != 0)
        .filter_map(move |(dx, dy)| {
            let (nx, ny) = (x + dx, y + dy);
            (nx >= 0 && ny >= 0 && nx < w && ny < h).then_some((ny * w + nx) as usize)
        })
        .filter(move |&j| keep(j))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bilinear_matches_texel_centres() {
        let mut p = LightmapPage::black(2, 1);
        p.texels[0] = Vec3::ZERO;
        p.texels[1] = Vec3::ONE;
        assert_eq!(p.sample_bilinear(0.25, 0.5), Vec3::ZERO);
        assert_eq!(p.sample_bilinear(0.75, 0.5), Vec3::ONE);
        assert!((p.sample_bilinear(0.5, 0.5) - Vec3::splat(0.5)).length() < 1e-6);
        // Clamped beyond the edge.
        assert_eq!(p.sample_bilinear(1.0, 0.5), Vec3::ONE);
    }
}
