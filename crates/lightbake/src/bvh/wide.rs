//! A four-wide BVH (the layout of Embree's SSE `BVH4`; Wald et al., "Embree: a kernel
//! framework for efficient CPU ray tracing", 2014) collapsed from obvhs' binary PLOC tree,
//! traversed four child boxes and four triangles at a time with glam's `Vec4` (SSE on x86-64,
//! no `unsafe`); the triangles are tested with the watertight test of
//! [`super::watertight`].
//!
//! Why not obvhs' own compressed wide BVH: its child boxes are quantised to bytes for GPUs,
//! and decoding them (48 byte-to-float conversions per node) cost more than the slab tests on
//! this CPU; the uncompressed layout traces 2× faster on baker rays (docs/benchmarks.md).
//!
//! # Robustness
//! Slab distances are computed as `(plane − origin) · (1 / direction)` and every exit distance
//! is scaled by 1 + 2γ₃ (Ize, "Robust BVH Ray Traversal", JCGT 2013), so a ray grazing a box
//! of zero thickness (an axis-aligned wall) still enters it, whatever the scene's scale. A zero
//! direction component inverts to ±`f32::MAX`, not to a small constant, so rays nearly along
//! an axis keep their true slab distances.

use glam::{Vec3, Vec4};
use obvhs::bvh2::Bvh2;

use super::watertight::{Shear, edge_functions_f64};

/// Most triangles in a leaf (in packets of four).
pub const LEAF_SIZE: usize = 8;

/// Packet index bits of a leaf reference; the bits above (below `LEAF_BIT`) hold the packet
/// count minus one.
const PACKET_BITS: u32 = 28;

/// Stack entries a traversal needs on the machine stack; deeper trees use a heap stack.
const INLINE_STACK: usize = 192;
/// A smaller machine stack for shallow trees (see [`Bvh4::with_stack`]).
const SMALL_STACK: usize = 16;

/// Child reference: an inner node index, a leaf (`LEAF_BIT` | packet index) or `EMPTY`.
const LEAF_BIT: u32 = 1 << 31;
const EMPTY: u32 = u32::MAX;

/// Exit-distance scale 1 + 2γ₃ rounded up (γₙ = nε / (1 − nε), ε = 2⁻²⁴).
const EXIT_SCALE: f32 = 1.0 + 4.0 * f32::EPSILON;

/// Four child boxes, structure of arrays, and their references.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub struct Node4 {
    /// Lower corners of the four child boxes (x, y, z rows); `+∞` for an empty slot.
    lo: [Vec4; 3],
    /// Upper corners; `−∞` for an empty slot.
    hi: [Vec4; 3],
    /// Child references.
    child: [u32; 4],
}

/// Four triangles, structure of arrays: their three vertices, exactly as given (the
/// watertight test needs the bits two triangles share on an edge to be the same).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
pub struct Tri4 {
    v: [[Vec4; 3]; 3],
    /// Primitive index of each lane (`u32::MAX` for padding lanes, whose vertices are zero).
    id: [u32; 4],
}

/// A ray prepared for the slab tests and the watertight triangle test.
#[derive(Clone, Copy, Debug)]
pub struct Ray4 {
    /// 1 / direction; ±`f32::MAX` where that overflows.
    inv: [Vec4; 3],
    org: [Vec4; 3],
    /// The ray's frame for the triangle test.
    shear: Shear,
    /// The shear's factors, splatted.
    s4: [Vec4; 3],
    /// Per axis: the direction is negative (near planes are the upper corners).
    neg: [bool; 3],
    /// Entry bound.
    pub tmin: f32,
    /// Exit bound (shrinks as closer hits are found).
    pub tmax: f32,
}

impl Ray4 {
    /// A ray from `origin` along unit `dir` for t in [tmin, tmax].
    #[inline]
    pub fn new(origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Self {
        let inv = |d: f32| {
            let i = 1.0 / d;
            if i.is_finite() {
                i
            } else {
                f32::MAX.copysign(d)
            }
        };
        let shear = Shear::new(dir);
        Self {
            inv: [dir.x, dir.y, dir.z].map(|d| Vec4::splat(inv(d))),
            org: [origin.x, origin.y, origin.z].map(Vec4::splat),
            shear,
            s4: shear.s.map(Vec4::splat),
            neg: [dir.x < 0.0, dir.y < 0.0, dir.z < 0.0],
            tmin,
            tmax,
        }
    }
}

/// The four-wide BVH over a triangle list (primitive ids index that list).
#[derive(Clone, Debug, Default)]
pub struct Bvh4 {
    nodes: Vec<Node4>,
    tris: Vec<Tri4>,
    /// Root reference (a leaf when the whole scene fits in one, `EMPTY` with no triangles).
    root: u32,
    /// Largest number of stack entries a traversal can need.
    stack_need: usize,
}

/// A hit in a [`Bvh4`]: (primitive id, t, u, v).
pub type Hit4 = (u32, f32, f32, f32);

impl Bvh4 {
    /// Collapses obvhs' binary tree into four-wide nodes: each node opens the largest-area
    /// inner child of its current set until it has four (the greedy surface-area collapse of
    /// Wald et al. 2008, "Getting rid of packets"); subtrees of at most [`LEAF_SIZE`] triangles
    /// become one leaf packet. `tris[k]` are the vertices of primitive `k`.
    pub fn collapse(bvh2: &Bvh2, tris: &[[Vec3; 3]]) -> Self {
        let mut out = Self {
            root: EMPTY,
            ..Self::default()
        };
        if bvh2.nodes.is_empty() || tris.is_empty() {
            return out;
        }
        // Triangles under each binary node.
        let mut count = vec![0u32; bvh2.nodes.len()];
        count_prims(bvh2, 0, &mut count);
        out.nodes.reserve(tris.len() / 2 + 1);
        out.tris.reserve(tris.len() / 2 + 1);
        let mut need = 0;
        out.root = out.emit(bvh2, &count, tris, 0, 1, &mut need);
        out.stack_need = need + 1;
        out
    }

    /// Emits binary subtree `b` and returns its reference; `need` collects the most stack
    /// entries a traversal holds, with `pending` waiting when it reaches `b`.
    fn emit(
        &mut self,
        bvh2: &Bvh2,
        count: &[u32],
        tris: &[[Vec3; 3]],
        b: usize,
        pending: usize,
        need: &mut usize,
    ) -> u32 {
        if count[b] as usize <= LEAF_SIZE {
            let mut prims = Vec::with_capacity(LEAF_SIZE);
            collect_prims(bvh2, b, &mut prims);
            let first = self.tris.len() as u32;
            assert!(first < 1 << PACKET_BITS, "too many triangles for the BVH");
            let packets = prims.chunks(4).map(|chunk| pack(chunk, tris));
            self.tris.extend(packets);
            let count = self.tris.len() as u32 - first;
            return LEAF_BIT | ((count - 1) << PACKET_BITS) | first;
        }
        // Open the largest-area inner child until there are four.
        let n = &bvh2.nodes[b];
        let mut kids = vec![n.first_index as usize, n.first_index as usize + 1];
        while kids.len() < 4 {
            let open = kids
                .iter()
                .enumerate()
                .filter(|&(_, &k)| count[k] as usize > LEAF_SIZE)
                .max_by(|a, b| {
                    let area = |k: usize| bvh2.nodes[k].aabb().half_area();
                    area(*a.1).total_cmp(&area(*b.1))
                })
                .map(|(i, _)| i);
            let Some(i) = open else { break };
            let k = kids.swap_remove(i);
            let first = bvh2.nodes[k].first_index as usize;
            kids.extend([first, first + 1]);
        }
        let index = self.nodes.len();
        self.nodes.push(Node4 {
            lo: [Vec4::INFINITY; 3],
            hi: [Vec4::NEG_INFINITY; 3],
            child: [EMPTY; 4],
        });
        *need = (*need).max(pending + kids.len() - 1);
        for (lane, &k) in kids.iter().enumerate() {
            let r = self.emit(bvh2, count, tris, k, pending + kids.len() - 1, need);
            let aabb = bvh2.nodes[k].aabb();
            let node = &mut self.nodes[index];
            node.child[lane] = r;
            for axis in 0..3 {
                node.lo[axis][lane] = aabb.min[axis];
                node.hi[axis][lane] = aabb.max[axis];
            }
        }
        index as u32
    }

    /// The packets of leaf reference `r`.
    #[inline(always)]
    fn leaf(&self, r: u32) -> &[Tri4] {
        let first = (r & ((1 << PACKET_BITS) - 1)) as usize;
        let count = ((r & !LEAF_BIT) >> PACKET_BITS) as usize + 1;
        &self.tris[first..first + count]
    }

    /// Number of four-wide nodes and leaf packets.
    pub fn sizes(&self) -> (usize, usize) {
        (self.nodes.len(), self.tris.len())
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        self.nodes.len() * size_of::<Node4>() + self.tris.len() * size_of::<Tri4>()
    }

    /// Calls `leaf` on every triangle packet of the leaves the ray enters (closest hit when
    /// `leaf` shrinks `ray.tmax`; any hit when it returns `true` to stop). Children are visited
    /// nearest first when `ordered`.
    #[inline(always)]
    fn traverse(
        &self,
        ray: &mut Ray4,
        ordered: bool,
        stack: &mut [(u32, f32)],
        mut leaf: impl FnMut(&Tri4, &mut Ray4) -> bool,
    ) {
        if self.root == EMPTY {
            return;
        }
        // The current node is kept out of the stack: of the children a node test enters, the
        // nearest becomes current and the others are pushed, farthest first.
        let mut sp = 0usize;
        let mut r = self.root;
        loop {
            if r & LEAF_BIT != 0 {
                for tri in self.leaf(r) {
                    if leaf(tri, ray) {
                        return;
                    }
                }
            } else {
                let node = &self.nodes[r as usize];
                let (near, mask) = node_hits(node, ray);
                if mask != 0 {
                    let near = near.to_array();
                    if mask.count_ones() == 1 {
                        r = node.child[mask.trailing_zeros() as usize];
                        continue;
                    }
                    if ordered && mask.count_ones() == 2 {
                        // The common case: two children, nearer one first.
                        let a = mask.trailing_zeros() as usize;
                        let b = (mask & (mask - 1)).trailing_zeros() as usize;
                        let (first, second) = if near[b] < near[a] { (b, a) } else { (a, b) };
                        stack[sp] = (node.child[second], near[second]);
                        sp += 1;
                        r = node.child[first];
                    } else if ordered {
                        let mut order = [(0f32, 0u32); 4];
                        let mut k = 0;
                        for lane in 0..4 {
                            if mask & (1 << lane) != 0 {
                                let item = (near[lane], node.child[lane]);
                                let mut j = k;
                                while j > 0 && order[j - 1].0 < item.0 {
                                    order[j] = order[j - 1];
                                    j -= 1;
                                }
                                order[j] = item;
                                k += 1;
                            }
                        }
                        for &(t, c) in &order[..k - 1] {
                            stack[sp] = (c, t);
                            sp += 1;
                        }
                        r = order[k - 1].1;
                    } else {
                        let mut m = mask;
                        r = node.child[m.trailing_zeros() as usize];
                        m &= m - 1;
                        while m != 0 {
                            let lane = m.trailing_zeros() as usize;
                            stack[sp] = (node.child[lane], near[lane]);
                            sp += 1;
                            m &= m - 1;
                        }
                    }
                    continue;
                }
            }
            // Pop the next child still in front of the closest hit.
            loop {
                if sp == 0 {
                    return;
                }
                sp -= 1;
                let (c, t_enter) = stack[sp];
                if t_enter <= ray.tmax {
                    r = c;
                    break;
                }
            }
        }
    }

    /// Runs `f` with a traversal stack deep enough for this tree (on the machine stack when
    /// it fits).
    #[inline(always)]
    fn with_stack<R>(&self, f: impl FnOnce(&mut [(u32, f32)]) -> R) -> R {
        // The array is zeroed on every ray, so it is no larger than the tree needs: zeroing
        // all `INLINE_STACK` entries for a shallow tree is a measurable share of a bake.
        fn on_stack<const N: usize, R>(f: impl FnOnce(&mut [(u32, f32)]) -> R) -> R {
            f(&mut [(0u32, 0f32); N])
        }
        if self.stack_need <= SMALL_STACK {
            on_stack::<SMALL_STACK, R>(f)
        } else if self.stack_need <= INLINE_STACK {
            on_stack::<INLINE_STACK, R>(f)
        } else {
            f(&mut vec![(0u32, 0f32); self.stack_need])
        }
    }

    /// The closest hit with t in [ray.tmin, ray.tmax].
    #[inline]
    pub fn closest_hit(&self, ray: &mut Ray4) -> Option<Hit4> {
        let mut best = None;
        self.with_stack(|stack| {
            self.traverse(ray, true, stack, |tri, ray| {
                if let Some(h) = intersect4(tri, ray) {
                    ray.tmax = h.1;
                    best = Some(h);
                }
                false
            })
        });
        best
    }

    /// Whether any primitive has a hit with t in [ray.tmin, ray.tmax].
    #[inline]
    pub fn occluded(&self, ray: &mut Ray4) -> bool {
        let mut hit = false;
        self.with_stack(|stack| {
            self.traverse(ray, false, stack, |tri, ray| {
                hit = intersect4(tri, ray).is_some();
                hit
            })
        });
        hit
    }

    /// Whether `f(primitive)` is true for a primitive of a leaf whose box comes within
    /// `radius` of `center` (every such primitive is offered until one is accepted; `f` does
    /// the exact test).
    pub fn any_in_ball(&self, center: Vec3, radius: f32, mut f: impl FnMut(u32) -> bool) -> bool {
        if self.root == EMPTY {
            return false;
        }
        let c = [center.x, center.y, center.z].map(Vec4::splat);
        let r2 = Vec4::splat(radius * radius);
        // As in `traverse`: the current node is kept out of the stack, and of the children a
        // node test enters, one becomes current and the others (at most three) are pushed.
        self.with_stack(|stack| {
            let mut sp = 0usize;
            let mut r = self.root;
            loop {
                if r & LEAF_BIT != 0 {
                    for tri in self.leaf(r) {
                        for &id in &tri.id {
                            if id != u32::MAX && f(id) {
                                return true;
                            }
                        }
                    }
                } else {
                    let node = &self.nodes[r as usize];
                    // Squared distance from the centre to each child box (0 inside it; an
                    // empty slot's inverted box gives a distance beyond any radius).
                    let mut d2 = Vec4::ZERO;
                    for axis in 0..3 {
                        let below = (node.lo[axis] - c[axis]).max(Vec4::ZERO);
                        let above = (c[axis] - node.hi[axis]).max(Vec4::ZERO);
                        let d = below + above;
                        d2 += d * d;
                    }
                    let mut mask = d2.cmple(r2).bitmask();
                    if mask != 0 {
                        r = node.child[mask.trailing_zeros() as usize];
                        mask &= mask - 1;
                        while mask != 0 {
                            stack[sp] = (node.child[mask.trailing_zeros() as usize], 0.0);
                            sp += 1;
                            mask &= mask - 1;
                        }
                        continue;
                    }
                }
                if sp == 0 {
                    return false;
                }
                sp -= 1;
                r = stack[sp].0;
            }
        })
    }

    /// Checks the invariants: every primitive `0..prim_count` sits in exactly one leaf lane,
    /// every child box contains its subtree's triangles, and the stack bound holds.
    ///
    /// # Panics
    /// When an invariant is broken.
    #[cfg_attr(not(feature = "internals"), allow(dead_code))] // for the tests and benchmarks
    pub fn validate(&self, prim_count: usize) {
        let mut seen = vec![false; prim_count];
        if self.root != EMPTY {
            let (lo, hi, depth) = self.check(self.root, &mut seen, 1);
            assert!(lo.cmple(hi).all(), "root box is empty");
            assert!(
                depth <= self.stack_need,
                "stack bound {} < {depth}",
                self.stack_need
            );
        }
        for (k, s) in seen.iter().enumerate() {
            assert!(s, "primitive {k} is in no leaf");
        }
    }

    /// Bounds of subtree `r` (checked against its parent by the caller) and the stack entries
    /// it needs with `pending` entries already waiting.
    #[cfg_attr(not(feature = "internals"), allow(dead_code))] // for the tests and benchmarks
    fn check(&self, r: u32, seen: &mut [bool], pending: usize) -> (Vec3, Vec3, usize) {
        if r & LEAF_BIT != 0 {
            let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
            for (t, lane) in self
                .leaf(r)
                .iter()
                .flat_map(|t| (0..4).map(move |l| (t, l)))
            {
                let id = t.id[lane];
                if id == u32::MAX {
                    continue;
                }
                assert!(!seen[id as usize], "primitive {id} is in two leaves");
                seen[id as usize] = true;
                for v in lane_vertices(t, lane) {
                    lo = lo.min(v);
                    hi = hi.max(v);
                }
            }
            return (lo, hi, pending);
        }
        let node = &self.nodes[r as usize];
        let live = node.child.iter().filter(|&&c| c != EMPTY).count();
        assert!(live >= 2, "node {r} has {live} children");
        let (mut lo, mut hi, mut depth) = (Vec3::INFINITY, Vec3::NEG_INFINITY, pending);
        for lane in 0..4 {
            let c = node.child[lane];
            if c == EMPTY {
                continue;
            }
            let (clo, chi, d) = self.check(c, seen, pending + live - 1);
            let blo = Vec3::new(node.lo[0][lane], node.lo[1][lane], node.lo[2][lane]);
            let bhi = Vec3::new(node.hi[0][lane], node.hi[1][lane], node.hi[2][lane]);
            // Leaf vertices are rebuilt as v0 + edge, which may round by an ulp.
            let tol = clo.abs().max(chi.abs()).max_element() * (4.0 * f32::EPSILON);
            assert!(
                (blo - tol).cmple(clo).all() && chi.cmple(bhi + tol).all(),
                "node {r} lane {lane}: box {blo}..{bhi} does not hold {clo}..{chi}"
            );
            lo = lo.min(blo);
            hi = hi.max(bhi);
            depth = depth.max(d);
        }
        (lo, hi, depth)
    }
}

/// Fills `count[b]` (and below) with the number of primitives under binary node `b`.
fn count_prims(bvh2: &Bvh2, b: usize, count: &mut [u32]) -> u32 {
    let n = &bvh2.nodes[b];
    count[b] = if n.is_leaf() {
        n.prim_count
    } else {
        let first = n.first_index as usize;
        count_prims(bvh2, first, count) + count_prims(bvh2, first + 1, count)
    };
    count[b]
}

/// The leaves (primitive ids) under binary node `b`.
fn collect_prims(bvh2: &Bvh2, b: usize, out: &mut Vec<u32>) {
    let n = &bvh2.nodes[b];
    if n.is_leaf() {
        let first = n.first_index as usize;
        out.extend_from_slice(&bvh2.primitive_indices[first..first + n.prim_count as usize]);
    } else {
        collect_prims(bvh2, n.first_index as usize, out);
        collect_prims(bvh2, n.first_index as usize + 1, out);
    }
}

/// Packs up to four triangles; unused lanes have zero vertices (their edge functions are all
/// zero, so they never hit).
fn pack(prims: &[u32], tris: &[[Vec3; 3]]) -> Tri4 {
    debug_assert!(!prims.is_empty() && prims.len() <= LEAF_SIZE);
    let mut t = Tri4 {
        v: [[Vec4::ZERO; 3]; 3],
        id: [u32::MAX; 4],
    };
    for (lane, &p) in prims.iter().enumerate() {
        for (k, vertex) in tris[p as usize].iter().enumerate() {
            for axis in 0..3 {
                t.v[k][axis][lane] = vertex[axis];
            }
        }
        t.id[lane] = p;
    }
    t
}

/// World vertices of lane `lane`.
fn lane_vertices(t: &Tri4, lane: usize) -> [Vec3; 3] {
    t.v.map(|v| Vec3::new(v[0][lane], v[1][lane], v[2][lane]))
}

/// Slab test of the four child boxes: entry distances and the mask of boxes whose
/// [entry, exit] meets [tmin, tmax].
#[inline(always)]
fn node_hits(node: &Node4, ray: &Ray4) -> (Vec4, u32) {
    let slab = |axis: usize| {
        let (near, far) = if ray.neg[axis] {
            (node.hi[axis], node.lo[axis])
        } else {
            (node.lo[axis], node.hi[axis])
        };
        (
            (near - ray.org[axis]) * ray.inv[axis],
            (far - ray.org[axis]) * ray.inv[axis],
        )
    };
    let (nx, fx) = slab(0);
    let (ny, fy) = slab(1);
    let (nz, fz) = slab(2);
    let enter = nx.max(ny).max(nz).max(Vec4::splat(ray.tmin));
    let exit = (fx.min(fy).min(fz) * EXIT_SCALE).min(Vec4::splat(ray.tmax));
    (enter, enter.cmple(exit).bitmask())
}

/// The watertight test ([`super::watertight`]) against four triangles at once: the nearest
/// hit with t in [tmin, tmax], as (primitive id, t, u, v).
#[inline(always)]
fn intersect4(tri: &Tri4, ray: &Ray4) -> Option<Hit4> {
    let [kx, ky, kz] = ray.shear.axes;
    let [sx, sy, sz] = ray.s4;
    // The vertices relative to the origin, sheared into the ray's frame.
    let rel = |k: usize| {
        let v = &tri.v[k];
        let z = v[kz] - ray.org[kz];
        (
            v[kx] - ray.org[kx] - sx * z,
            v[ky] - ray.org[ky] - sy * z,
            z,
        )
    };
    let (ax, ay, az) = rel(0);
    let (bx, by, bz) = rel(1);
    let (cx, cy, cz) = rel(2);
    // The edge functions; exact zeros (a ray through an edge or a vertex) are redone in
    // double precision.
    let mut u = cx * by - cy * bx;
    let mut v = ax * cy - ay * cx;
    let mut w = bx * ay - by * ax;
    let zero = (u.cmpeq(Vec4::ZERO) | v.cmpeq(Vec4::ZERO) | w.cmpeq(Vec4::ZERO)).bitmask();
    if zero != 0 {
        (u, v, w) = redo_in_f64(tri, ray, zero, (u, v, w));
    }
    let negative = u.cmplt(Vec4::ZERO) | v.cmplt(Vec4::ZERO) | w.cmplt(Vec4::ZERO);
    let positive = u.cmpgt(Vec4::ZERO) | v.cmpgt(Vec4::ZERO) | w.cmpgt(Vec4::ZERO);
    let det = u + v + w;
    // t·det, compared scaled by |det| (signs folded in), so only lanes that hit pay for the
    // division (as Embree's intersectors do).
    let t = (u * az + v * bz + w * cz) * sz;
    let sign = det.signum();
    let abs_det = det.abs();
    let t_abs = t * sign;
    let inside = (negative & positive).bitmask() ^ 0b1111;
    let ok = abs_det.cmpgt(Vec4::ZERO)
        & abs_det.cmplt(Vec4::INFINITY)
        & t_abs.cmpge(abs_det * ray.tmin)
        & t_abs.cmple(abs_det * ray.tmax);
    let mask = ok.bitmask() & inside;
    if mask == 0 {
        return None;
    }
    let inv = Vec4::ONE / det;
    let (t, u, v) = (
        (t * inv).to_array(),
        (v * inv).to_array(),
        (w * inv).to_array(),
    );
    let mut best: Option<Hit4> = None;
    for lane in 0..4 {
        if mask & (1 << lane) != 0 && best.is_none_or(|b| t[lane] < b.1) {
            // The division may round just outside the interval the scaled test accepted.
            let t = t[lane].clamp(ray.tmin, ray.tmax);
            best = Some((tri.id[lane], t, u[lane], v[lane]));
        }
    }
    best
}

/// The edge functions of the lanes in `lanes` (a bit mask) recomputed in double precision;
/// padding lanes keep theirs (zero: they never hit).
#[cold]
#[inline(never)]
fn redo_in_f64(tri: &Tri4, ray: &Ray4, lanes: u32, uvw: (Vec4, Vec4, Vec4)) -> (Vec4, Vec4, Vec4) {
    let (mut u, mut v, mut w) = (uvw.0.to_array(), uvw.1.to_array(), uvw.2.to_array());
    let origin = Vec3::new(ray.org[0].x, ray.org[1].x, ray.org[2].x);
    for lane in 0..4 {
        if lanes & (1 << lane) == 0 || tri.id[lane] == u32::MAX {
            continue;
        }
        let [a, b, c] = lane_vertices(tri, lane).map(|p| p - origin);
        [u[lane], v[lane], w[lane]] = edge_functions_f64(&ray.shear, a, b, c);
    }
    (
        Vec4::from_array(u),
        Vec4::from_array(v),
        Vec4::from_array(w),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn packet_test_matches_one_triangle_at_a_time() {
        let tris = [
            [Vec3::ZERO, Vec3::X, Vec3::Y],
            [
                Vec3::new(0.0, 0.0, 1.0),
                Vec3::new(1.0, 0.0, 1.0),
                Vec3::new(0.0, 1.0, 1.0),
            ],
            [Vec3::ZERO, Vec3::ZERO, Vec3::ZERO],
        ];
        let packet = pack(&[0, 1, 2], &tris);
        // From below, the nearer triangle (z = 0) wins.
        let ray = Ray4::new(Vec3::new(0.2, 0.3, -1.0), Vec3::Z, 0.0, f32::INFINITY);
        let (id, t, u, v) = intersect4(&packet, &ray).unwrap();
        assert_eq!(id, 0);
        assert!((t - 1.0).abs() < 1e-6 && (u - 0.2).abs() < 1e-6 && (v - 0.3).abs() < 1e-6);
        // From above, the z = 1 triangle; a short ray misses both; the degenerate lane never hits.
        let ray = Ray4::new(Vec3::new(0.2, 0.3, 2.0), -Vec3::Z, 0.0, f32::INFINITY);
        assert_eq!(intersect4(&packet, &ray).unwrap().0, 1);
        let ray = Ray4::new(Vec3::new(0.2, 0.3, 2.0), -Vec3::Z, 0.0, 0.5);
        assert!(intersect4(&packet, &ray).is_none());
        let ray = Ray4::new(Vec3::new(0.0, 0.0, -1.0), Vec3::Z, 0.0, f32::INFINITY);
        assert!(intersect4(&packet, &ray).is_some_and(|h| h.0 != 2));
    }

    #[test]
    fn axis_aligned_rays_keep_true_slab_distances() {
        // A ray along x with a tiny y component passes 1e-6 below a box's top face; obvhs'
        // inverse (±1/ε for |d| ≤ ε) would make the y slab end after 8 m and miss the box at
        // 20 m.
        let ray = Ray4::new(Vec3::ZERO, Vec3::new(1.0, 1e-9, 0.0), 0.0, f32::INFINITY);
        let node = Node4 {
            lo: [
                Vec4::new(20.0, f32::INFINITY, f32::INFINITY, f32::INFINITY),
                Vec4::new(-1.0, f32::INFINITY, f32::INFINITY, f32::INFINITY),
                Vec4::new(-1.0, f32::INFINITY, f32::INFINITY, f32::INFINITY),
            ],
            hi: [
                Vec4::new(
                    21.0,
                    f32::NEG_INFINITY,
                    f32::NEG_INFINITY,
                    f32::NEG_INFINITY,
                ),
                Vec4::new(
                    1e-6,
                    f32::NEG_INFINITY,
                    f32::NEG_INFINITY,
                    f32::NEG_INFINITY,
                ),
                Vec4::new(1.0, f32::NEG_INFINITY, f32::NEG_INFINITY, f32::NEG_INFINITY),
            ],
            child: [0, EMPTY, EMPTY, EMPTY],
        };
        assert_eq!(node_hits(&node, &ray).1, 0b0001);
        // Exactly along an axis (zero components) and a flat box (zero thickness in x).
        let ray = Ray4::new(Vec3::new(-5.0, 0.5, 0.5), Vec3::X, 0.0, f32::INFINITY);
        let mut flat = node;
        flat.lo[0] = Vec4::new(3.0, f32::INFINITY, f32::INFINITY, f32::INFINITY);
        flat.hi[0] = Vec4::new(3.0, f32::NEG_INFINITY, f32::NEG_INFINITY, f32::NEG_INFINITY);
        flat.lo[1][0] = 0.0;
        flat.hi[1][0] = 1.0;
        assert_eq!(node_hits(&flat, &ray).1, 0b0001);
    }
}
