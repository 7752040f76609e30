//! Many VPLs gathered through cuts of a tree over them: lightcuts (Walter, Fernandez, Arbree,
//! Bala, Donikian & Greenberg 2005, "Lightcuts: a scalable approach to illumination",
//! SIGGRAPH 2005) with the stochastic representatives of Yuksel 2019 ("Stochastic
//! Lightcuts", HPG 2019).
//!
//! The VPLs that are samples (diffuse and directional; punctual lights stay exact) sit in a
//! binary tree: median cuts along the longest axis of their positions (diffuse VPLs) or of
//! the directions their light arrives from (directional ones). Each node keeps the bounds of
//! its VPLs' points, the cone of their normals (or of their directions), and their total
//! power; the leaves of any node are one contiguous run of the leaf order.
//!
//! A *cut* is a set of nodes whose runs together hold every VPL that can reach a group of
//! texels. It is chosen once per group (a tile of texels close in space that face about the
//! same way): from the roots, the node whose bound on the light it can give any texel of the
//! group is largest is split into its children, until the cut holds `size` nodes or only
//! leaves are left; nodes whose bound is zero (wholly behind every texel of the group, or
//! facing away from all of them) are dropped, which loses nothing. Each texel then takes one
//! VPL from each node of the cut, picked in proportion to its power, and weighs its light by
//! the node's power over the VPL's: the sum is unbiased for the light of every VPL, with the
//! noise of one sample per node instead of the blotches of a few VPLs. A leaf is its own VPL,
//! exactly.
//!
//! The bound of a node at a group of texels: its power over π times the clamped geometric term
//! G = cosθ_x·cosθ_y/r² ≤ min(b, cos⁺θ_x·cos⁺θ_y/d²), d the distance between the two boxes and
//! the cosines bounded by the two cones widened by the angle the other box subtends (Conty
//! Estevez & Kulla 2018, "Importance Sampling of Many Lights with Adaptive Tree Splitting",
//! eq. 3). Directional light is bounded by its irradiance times the receiving cosine.

use std::cmp::Ordering;
use std::collections::BinaryHeap;
use std::f32::consts::{FRAC_1_PI, FRAC_PI_2, PI};

use glam::Vec3;

use super::walk::{Vpl, VplKind};
use crate::color::luminance;

/// Bytes per VPL while the cut gather runs: the VPL itself, its copy in leaf order, two tree
/// nodes, its index and its prefix sum of power.
pub const BYTES_PER_VPL: u64 = (2 * size_of::<Vpl>() + 2 * size_of::<Node>() + 4 + 8) as u64;

/// Angles are widened by this much (radians) so rounding never drops a node that can reach.
const ANGLE_SLACK: f32 = 1e-3;

/// One node: a leaf is one VPL, an inner node its two children (the left one follows it).
#[derive(Clone, Copy, Debug)]
struct Node {
    lo: Vec3,
    hi: Vec3,
    /// Axis of the cone of the VPLs' normals (diffuse) or of the directions their light
    /// arrives from (directional).
    axis: Vec3,
    /// Half-angle of that cone, radians.
    spread: f32,
    /// Luminance of the power (lm, diffuse) or of the irradiance facing it (lux, directional).
    power: f32,
    /// The node's run of the leaf order.
    start: u32,
    end: u32,
    /// The right child; `u32::MAX` for a leaf.
    right: u32,
    directional: bool,
}

/// A group of texels a cut is chosen for: the box of their points and the cone of their
/// normals.
#[derive(Clone, Copy, Debug)]
pub struct Receivers {
    /// Lower corner of the points' box, m.
    pub lo: Vec3,
    /// Upper corner, m.
    pub hi: Vec3,
    /// Axis of the normals' cone (unit).
    pub axis: Vec3,
    /// Half-angle of the normals' cone, radians (π: any way).
    pub spread: f32,
}

impl Receivers {
    /// The group of the points and shading normals given (at least one).
    pub fn around(points: impl Iterator<Item = (Vec3, Vec3)> + Clone) -> Self {
        let (lo, hi) = points.clone().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), (p, _)| (lo.min(p), hi.max(p)),
        );
        let (axis, spread) = cone(points.map(|(_, n)| n));
        Self {
            lo,
            hi,
            axis,
            spread,
        }
    }
}

/// The cone around unit vectors: their mean direction and the largest angle to it.
fn cone(dirs: impl Iterator<Item = Vec3> + Clone) -> (Vec3, f32) {
    let sum: Vec3 = dirs.clone().sum();
    let Some(axis) = sum.try_normalize() else {
        return (Vec3::Z, PI);
    };
    let spread = dirs.fold(0.0f32, |s, d| s.max(axis.dot(d).clamp(-1.0, 1.0).acos()));
    (axis, (spread + ANGLE_SLACK).min(PI))
}

/// An upper bound of cos⁺ of the angle between a direction of the cone (`axis`, `spread`)
/// and a vector of the box `[lo, hi]` (1 when the box holds the origin).
fn cos_bound(axis: Vec3, spread: f32, lo: Vec3, hi: Vec3) -> f32 {
    let m = 0.5 * (lo + hi);
    let r = 0.5 * (hi - lo).length();
    let len = m.length();
    if len <= r * 1.0001 + 1e-12 {
        return 1.0;
    }
    let subtended = (r / len).min(1.0).asin();
    let angle = axis.dot(m / len).clamp(-1.0, 1.0).acos();
    let t = (angle - spread - subtended - ANGLE_SLACK).max(0.0);
    if t >= FRAC_PI_2 { 0.0 } else { t.cos() }
}

/// The tree over the VPLs that are samples.
#[derive(Clone, Debug, Default)]
pub struct VplTree {
    nodes: Vec<Node>,
    /// Roots: the diffuse VPLs' tree and the directional ones'.
    roots: Vec<u32>,
    /// VPL indices in leaf order.
    order: Vec<u32>,
    /// The VPLs in leaf order (a node's picks read one run of memory).
    leaves: Vec<Vpl>,
    /// Σ luminance of the power of `order[..i]`.
    prefix: Vec<f64>,
}

/// One VPL as the build sees it: its index, its point (or direction), normal and power.
type Item = (u32, Vec3, Vec3, f32);

impl VplTree {
    /// The tree over the diffuse and directional VPLs of `vpls` with some power.
    pub fn build(vpls: &[Vpl]) -> Self {
        let mut diffuse: Vec<Item> = Vec::new();
        let mut directional: Vec<Item> = Vec::new();
        for (i, v) in vpls.iter().enumerate() {
            match v.kind {
                VplKind::Diffuse { normal } => {
                    let p = luminance(v.power);
                    if p.is_finite() && p > 0.0 {
                        diffuse.push((i as u32, v.position, normal, p));
                    }
                }
                VplKind::Directional {
                    direction,
                    irradiance,
                } => {
                    let p = luminance(irradiance);
                    if p.is_finite() && p > 0.0 {
                        directional.push((i as u32, -direction, -direction, p));
                    }
                }
                VplKind::Punctual { .. } => {}
            }
        }
        let n = diffuse.len() + directional.len();
        let mut tree = Self {
            nodes: Vec::with_capacity(2 * n),
            roots: Vec::new(),
            order: Vec::with_capacity(n),
            leaves: Vec::new(),
            prefix: vec![0.0],
        };
        for (items, dir) in [(&mut diffuse, false), (&mut directional, true)] {
            if !items.is_empty() {
                let root = tree.split(items, dir);
                tree.roots.push(root);
            }
        }
        tree.leaves = tree.order.iter().map(|&i| vpls[i as usize]).collect();
        tree
    }

    /// The VPL at position `k` of the leaf order.
    pub fn leaf(&self, k: u32) -> &Vpl {
        &self.leaves[k as usize]
    }

    /// The index (in the slice the tree was built from) of the VPL at position `k` of the
    /// leaf order.
    #[cfg(test)]
    fn original(&self, k: u32) -> u32 {
        self.order[k as usize]
    }

    fn split(&mut self, items: &mut [Item], directional: bool) -> u32 {
        let (lo, hi) = items.iter().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), i| (lo.min(i.1), hi.max(i.1)),
        );
        let (axis, spread) = cone(items.iter().map(|i| i.2));
        let power = items.iter().map(|i| i.3 as f64).sum::<f64>() as f32;
        let at = self.nodes.len() as u32;
        let start = self.order.len() as u32;
        self.nodes.push(Node {
            lo,
            hi,
            axis,
            spread,
            power,
            start,
            end: start,
            right: u32::MAX,
            directional,
        });
        if let [(i, _, _, p)] = items {
            self.order.push(*i);
            let last = *self.prefix.last().unwrap_or(&0.0);
            self.prefix.push(last + *p as f64);
        } else {
            let split_axis = (hi - lo).max_position();
            let mid = items.len() / 2;
            items.select_nth_unstable_by(mid, |a, b| {
                a.1[split_axis]
                    .total_cmp(&b.1[split_axis])
                    .then(a.0.cmp(&b.0))
            });
            let (left, right) = items.split_at_mut(mid);
            self.split(left, directional);
            let r = self.split(right, directional);
            self.nodes[at as usize].right = r;
        }
        self.nodes[at as usize].end = self.order.len() as u32;
        at
    }

    /// An upper bound of the irradiance (luminance, lux) node `at` can give any point of
    /// `r`, with the geometric term clamped at `clamp` (1/m²).
    fn bound(&self, at: u32, r: &Receivers, clamp: f32) -> f32 {
        let node = &self.nodes[at as usize];
        if node.directional {
            // The receiving cosine: the two cones' axes, less both spreads.
            let angle = r.axis.dot(node.axis).clamp(-1.0, 1.0).acos();
            let t = (angle - r.spread - node.spread - ANGLE_SLACK).max(0.0);
            return if t >= FRAC_PI_2 {
                0.0
            } else {
                node.power * t.cos()
            };
        }
        // Vectors from the node's points to the receivers' points.
        let (lo, hi) = (r.lo - node.hi, r.hi - node.lo);
        let sending = cos_bound(node.axis, node.spread, lo, hi);
        let receiving = cos_bound(r.axis, r.spread, -hi, -lo);
        if sending <= 0.0 || receiving <= 0.0 {
            return 0.0;
        }
        let gap = (node.lo - r.hi).max(r.lo - node.hi).max(Vec3::ZERO);
        let d2 = gap.length_squared();
        let g = if d2 > 0.0 {
            (sending * receiving / d2).min(clamp)
        } else {
            clamp
        };
        node.power * FRAC_1_PI * g
    }

    /// The cut for the group `r`: at most `size` nodes (or every leaf that can reach),
    /// in leaf order; `clamp` bounds the geometric term (1/m²).
    pub fn cut(&self, r: &Receivers, size: usize, clamp: f32) -> Vec<u32> {
        #[derive(PartialEq)]
        struct Entry(f32, u32);
        impl Eq for Entry {}
        impl PartialOrd for Entry {
            fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
                Some(self.cmp(other))
            }
        }
        impl Ord for Entry {
            fn cmp(&self, other: &Self) -> Ordering {
                self.0.total_cmp(&other.0).then(other.1.cmp(&self.1))
            }
        }
        let mut heap = BinaryHeap::new();
        let mut done = Vec::new();
        for &root in &self.roots {
            let b = self.bound(root, r, clamp);
            if b > 0.0 {
                heap.push(Entry(b, root));
            }
        }
        while done.len() + heap.len() < size.max(1) {
            let Some(Entry(_, at)) = heap.pop() else {
                break;
            };
            let node = &self.nodes[at as usize];
            if node.right == u32::MAX {
                done.push(at);
                continue;
            }
            for child in [at + 1, node.right] {
                let b = self.bound(child, r, clamp);
                if b > 0.0 {
                    heap.push(Entry(b, child));
                }
            }
        }
        done.extend(heap.into_iter().map(|e| e.1));
        done.sort_unstable_by_key(|&at| self.nodes[at as usize].start);
        done
    }

    /// Whether node `at` is one VPL.
    pub fn is_leaf(&self, at: u32) -> bool {
        self.nodes[at as usize].right == u32::MAX
    }

    /// One VPL of node `at` picked with `u` ∈ [0, 1) in proportion to its power (its
    /// position in the leaf order), and its weight: the node's power over the VPL's (1 for a
    /// leaf).
    pub fn pick(&self, at: u32, u: f64) -> (u32, f32) {
        let node = &self.nodes[at as usize];
        let (s, e) = (node.start as usize, node.end as usize);
        if e - s == 1 {
            return (s as u32, 1.0);
        }
        let (base, total) = (self.prefix[s], self.prefix[e] - self.prefix[s]);
        let target = base + u * total;
        // The last leaf whose run starts at or below the target.
        let k = (s + self.prefix[s + 1..e].partition_point(|&c| c <= target)).min(e - 1);
        let own = self.prefix[k + 1] - self.prefix[k];
        (k as u32, (total / own) as f32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn diffuse(k: u32, position: Vec3, normal: Vec3, power: f32) -> Vpl {
        Vpl {
            position,
            power: Vec3::splat(power),
            kind: VplKind::Diffuse { normal },
            depth: 1,
            path: k,
        }
    }

    /// A wall of VPLs facing +x at x = 0, and a floor of them facing up.
    fn room() -> Vec<Vpl> {
        let mut v = Vec::new();
        for k in 0..200u32 {
            let (a, b) = ((k % 20) as f32 * 0.1, (k / 20) as f32 * 0.2);
            v.push(diffuse(
                k,
                Vec3::new(0.0, a, b),
                Vec3::X,
                1.0 + (k % 3) as f32,
            ));
            v.push(diffuse(k + 200, Vec3::new(a, 0.0, b), Vec3::Y, 2.0));
        }
        v
    }

    #[test]
    fn a_cut_as_large_as_the_tree_is_every_vpl_that_can_reach() {
        let vpls = room();
        let tree = VplTree::build(&vpls);
        assert_eq!(tree.order.len(), 400);
        // Texels on a wall at x = 1 facing -x: the wall at x = 0 faces them, the floor
        // grazes them; nothing is dropped that can reach.
        let r = Receivers::around(
            (0..4).map(|k| (Vec3::new(1.0, 0.5 + 0.1 * k as f32, 1.0), Vec3::NEG_X)),
        );
        let cut = tree.cut(&r, 10_000, 1e6);
        assert!(cut.iter().all(|&at| tree.is_leaf(at)));
        let mut seen: Vec<u32> = cut
            .iter()
            .map(|&at| tree.original(tree.pick(at, 0.5).0))
            .collect();
        seen.sort_unstable();
        // Every wall VPL (in front, facing the texels) is in the cut.
        assert!((0..400).step_by(2).all(|i| seen.binary_search(&i).is_ok()));
        // Texels below the floor, facing down, can be reached by nothing.
        let under = Receivers::around(std::iter::once((Vec3::new(1.0, -1.0, 1.0), Vec3::NEG_Y)));
        assert!(tree.cut(&under, 64, 1e6).is_empty());
    }

    #[test]
    fn picks_follow_power_and_weigh_to_the_node_total() {
        let vpls = room();
        let tree = VplTree::build(&vpls);
        let root = tree.roots[0];
        let total: f64 = vpls.iter().map(|v| luminance(v.power) as f64).sum();
        let m = 100_000;
        let mut mean = 0.0f64;
        let mut counts = vec![0u32; vpls.len()];
        for j in 0..m {
            let (k, w) = tree.pick(root, (j as f64 + 0.5) / m as f64);
            let i = tree.original(k);
            // Each pick's weight times its power is the node's power.
            let p = luminance(vpls[i as usize].power) as f64;
            assert!((w as f64 * p - total).abs() < 1e-3 * total);
            mean += w as f64 * p / m as f64;
            counts[i as usize] += 1;
        }
        assert!((mean - total).abs() < 1e-3 * total);
        for (i, v) in vpls.iter().enumerate() {
            let expect = luminance(v.power) as f64 / total * m as f64;
            assert!((counts[i] as f64 - expect).abs() <= 1.0 + 1e-6, "{i}");
        }
    }

    #[test]
    fn the_bound_is_never_below_the_light_of_a_vpl_of_the_node() {
        let vpls = room();
        let tree = VplTree::build(&vpls);
        let clamp = 1.0 / (0.05f32 * 0.05);
        let points = [
            (Vec3::new(1.0, 0.5, 1.0), Vec3::NEG_X),
            (Vec3::new(0.5, 0.01, 0.3), Vec3::Y),
            (Vec3::new(0.01, 0.5, 0.3), Vec3::X),
            (
                Vec3::new(0.7, 1.5, 0.2),
                Vec3::new(-1.0, -1.0, 0.0).normalize(),
            ),
        ];
        for (p, n) in points {
            let r = Receivers::around(std::iter::once((p, n)));
            for at in 0..tree.nodes.len() as u32 {
                let node = tree.nodes[at as usize];
                let b = tree.bound(at, &r, clamp);
                for &i in &tree.order[node.start as usize..node.end as usize] {
                    let v = &vpls[i as usize];
                    let VplKind::Diffuse { normal } = v.kind else {
                        unreachable!()
                    };
                    let d = v.position - p;
                    let r2 = d.length_squared();
                    let l = d / r2.sqrt();
                    let g = (n.dot(l).max(0.0) * (-normal.dot(l)).max(0.0) / r2).min(clamp);
                    let e = luminance(v.power) * FRAC_1_PI * g;
                    assert!(b >= e * (1.0 - 1e-4), "node {at}: bound {b} < {e}");
                }
            }
        }
    }
}
