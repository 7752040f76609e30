//! Many lights sampled by importance (beyond [`PER_TEXEL_LIGHTS`] per instance; below, each
//! texel weighs the lights itself: `direct::light_choice`): a binary tree over the lights that
//! sit somewhere (point, spot, rect), each node holding its lights' bounds and total power,
//! walked from the root to one light with probability in proportion to each child's
//! importance at the shading point — its power over the squared distance to its bounds'
//! centre (clamped below at half their diagonal squared), zero when the bounds lie wholly
//! behind the surface. The estimate f·V/p of the picked light is unbiased whenever every light
//! that can reach the point has a non-zero probability, which the clamp and the half-space
//! test keep. It cannot see walls: where most lights are in other rooms, it spends most
//! samples on them.
//!
//! Light trees for direct light: Conty Estevez & Kulla, *Importance Sampling of Many Lights
//! with Adaptive Tree Splitting* (HPG 2018); pbrt-v4's `BVHLightSampler`. This is their
//! simplest form (no orientation cones): one light per footprint sample, so the cost is
//! O(log n) per sample however many lights there are.

use glam::Vec3;

use super::{LightSource, SceneDisc};
use crate::color::luminance;
use crate::scene::{LightKind, Scene};

/// Above this many lights reaching an instance, the direct pass picks lights per footprint
/// sample for its texels instead of evaluating every light: four by each texel's own weights
/// (`direct::light_choice`, [`PICKS_PER_SAMPLE`]) up to [`PER_TEXEL_LIGHTS`], one from
/// a [`LightTree`] beyond. Every light costs a shadow ray per sample, so a level lit by a few
/// dozen lamps spent most of its bake on them: on the OpenArena levels at medium (22–30
/// lamps), evaluating all of them took 39–48% of the bake and gave direct noise a tenth of the
/// texel grid's error; with four picks the bake traces 1.7–2.1× fewer rays at the same
/// measured error (docs/benchmarks.md, "Many lights").
pub const MANY_LIGHTS: usize = 8;

/// Lights a texel's own weights (`direct::light_choice`) pick per footprint sample, each
/// weighted by one over this many times its probability: more picks lower the noise of the
/// choice at one shadow ray each, beside the footprint's own noise, which they do not lower.
/// On `kaos` (30 lamps) at medium one pick gave 2.07× fewer rays than evaluating every lamp
/// and an 11% higher measured error; four give 1.74× fewer and the same error.
pub const PICKS_PER_SAMPLE: u32 = 4;

/// Up to this many lights reaching an instance, each texel picks its lights per footprint
/// sample by weights of its own (each light's unoccluded light and its visibility from the
/// texel: `direct::light_choice`); beyond, a [`LightTree`] picks.
pub const PER_TEXEL_LIGHTS: usize = 512;

/// One node: a leaf names a light, an inner node its two children (the left one follows it).
#[derive(Clone, Copy, Debug)]
struct Node {
    lo: Vec3,
    hi: Vec3,
    power: f32,
    /// Leaf: the light; inner: the right child.
    index: u32,
    leaf: bool,
}

/// The tree over a scene's lights with a position.
#[derive(Clone, Debug, Default)]
pub struct LightTree {
    nodes: Vec<Node>,
    /// The lights in the tree, sorted.
    members: Vec<u32>,
}

impl LightTree {
    /// The lights of `scene` listed in `lights` that have a position (point, spot, rect) and
    /// some power, in a tree (median cuts along the longest axis).
    pub fn build(scene: &Scene, lights: &[u32], disc: &SceneDisc) -> Self {
        let mut items: Vec<(u32, Vec3, f32)> = lights
            .iter()
            .filter_map(|&li| {
                let light = &scene.lights[li as usize];
                let placed = !matches!(light.kind, LightKind::Directional { .. });
                let power = luminance(light.power(disc));
                (placed && power.is_finite() && power > 0.0).then_some((li, light.position, power))
            })
            .collect();
        let mut members: Vec<u32> = items.iter().map(|i| i.0).collect();
        members.sort_unstable();
        let mut tree = Self {
            nodes: Vec::with_capacity(2 * items.len()),
            members,
        };
        if !items.is_empty() {
            tree.split(&mut items);
        }
        tree
    }

    /// Whether the tree holds no light.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// Whether light `li` is in the tree.
    pub fn holds(&self, li: u32) -> bool {
        self.members.binary_search(&li).is_ok()
    }

    fn split(&mut self, items: &mut [(u32, Vec3, f32)]) -> usize {
        let (lo, hi) = items.iter().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), i| (lo.min(i.1), hi.max(i.1)),
        );
        let power: f32 = items.iter().map(|i| i.2).sum();
        let at = self.nodes.len();
        if let [(li, _, _)] = items {
            self.nodes.push(Node {
                lo,
                hi,
                power,
                index: *li,
                leaf: true,
            });
            return at;
        }
        self.nodes.push(Node {
            lo,
            hi,
            power,
            index: 0,
            leaf: false,
        });
        let axis = (hi - lo).max_position();
        let mid = items.len() / 2;
        items.select_nth_unstable_by(mid, |a, b| {
            a.1[axis].total_cmp(&b.1[axis]).then(a.0.cmp(&b.0))
        });
        let (left, right) = items.split_at_mut(mid);
        self.split(left);
        let r = self.split(right);
        self.nodes[at].index = r as u32;
        at
    }

    /// A node's importance at point `p` with normal `n`.
    fn importance(node: &Node, p: Vec3, n: Vec3) -> f32 {
        // Wholly behind the surface: no light of it reaches the front.
        let behind = (0..8).all(|k| {
            let c = Vec3::new(
                if k & 1 == 0 { node.lo.x } else { node.hi.x },
                if k & 2 == 0 { node.lo.y } else { node.hi.y },
                if k & 4 == 0 { node.lo.z } else { node.hi.z },
            );
            (c - p).dot(n) <= 0.0
        });
        if behind {
            return 0.0;
        }
        let centre = 0.5 * (node.lo + node.hi);
        let half_diagonal2 = 0.25 * (node.hi - node.lo).length_squared();
        let d2 = (centre - p).length_squared().max(half_diagonal2).max(1e-8);
        node.power / d2
    }

    /// One light for the point `p` with normal `n`, picked with the number `u` ∈ [0, 1), and
    /// the probability it was picked with; `None` when no light can reach the point.
    pub fn pick(&self, p: Vec3, n: Vec3, mut u: f32) -> Option<(u32, f32)> {
        let mut at = 0usize;
        let mut pdf = 1.0f32;
        let root = self.nodes.first()?;
        if Self::importance(root, p, n) <= 0.0 {
            return None;
        }
        loop {
            let node = &self.nodes[at];
            if node.leaf {
                return Some((node.index, pdf));
            }
            let (l, r) = (at + 1, node.index as usize);
            let il = Self::importance(&self.nodes[l], p, n);
            let ir = Self::importance(&self.nodes[r], p, n);
            let total = il + ir;
            if !(total > 0.0 && total.is_finite()) {
                return None;
            }
            let pl = il / total;
            if u < pl {
                u = (u / pl).min(1.0 - f32::EPSILON);
                pdf *= pl;
                at = l;
            } else {
                u = ((u - pl) / (1.0 - pl)).clamp(0.0, 1.0 - f32::EPSILON);
                pdf *= 1.0 - pl;
                at = r;
            }
        }
    }

    /// The probability [`Self::pick`] gives light `li` at `p` with normal `n` (0 when absent).
    #[cfg(test)]
    fn probability(&self, li: u32, p: Vec3, n: Vec3) -> f32 {
        // Walk down every path; the tree is small enough in tests.
        fn walk(tree: &LightTree, at: usize, li: u32, p: Vec3, n: Vec3) -> Option<f32> {
            let node = &tree.nodes[at];
            if node.leaf {
                return (node.index == li).then_some(1.0);
            }
            let (l, r) = (at + 1, node.index as usize);
            let il = LightTree::importance(&tree.nodes[l], p, n);
            let ir = LightTree::importance(&tree.nodes[r], p, n);
            let total = il + ir;
            if total <= 0.0 {
                return None;
            }
            walk(tree, l, li, p, n)
                .map(|q| q * il / total)
                .or_else(|| walk(tree, r, li, p, n).map(|q| q * ir / total))
        }
        if self.nodes.is_empty() || Self::importance(&self.nodes[0], p, n) <= 0.0 {
            return 0.0;
        }
        walk(self, 0, li, p, n).unwrap_or(0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Light, LightBake};

    fn lamps(n: usize) -> Scene {
        let mut s = Scene::default();
        for k in 0..n {
            s.lights.push(Light {
                name: format!("l{k}"),
                kind: LightKind::Point,
                color: Vec3::ONE,
                intensity: 1.0 + (k % 7) as f32,
                range: None,
                position: Vec3::new((k % 10) as f32, 1.0 + (k / 10) as f32 * 0.3, (k % 3) as f32),
                direction: Vec3::NEG_Y,
                bake: LightBake::Full,
            });
        }
        s
    }

    #[test]
    fn picks_every_light_that_can_reach_with_probabilities_summing_to_one() {
        let s = lamps(37);
        let ids: Vec<u32> = (0..37).collect();
        let disc = SceneDisc {
            centre: Vec3::ZERO,
            radius: 10.0,
        };
        let tree = LightTree::build(&s, &ids, &disc);
        assert_eq!(tree.members.len(), 37);
        let (p, n) = (Vec3::new(3.0, 0.0, 1.0), Vec3::Y);
        let total: f32 = ids.iter().map(|&li| tree.probability(li, p, n)).sum();
        assert!((total - 1.0).abs() < 1e-4, "{total}");
        assert!(ids.iter().all(|&li| tree.probability(li, p, n) > 0.0));
        // Picking by u over [0, 1) gives each light in proportion to its probability, and the
        // pdf returned is that probability.
        let m = 200_000;
        let mut counts = [0u32; 37];
        for k in 0..m {
            let (li, pdf) = tree.pick(p, n, (k as f32 + 0.5) / m as f32).unwrap();
            assert!((pdf - tree.probability(li, p, n)).abs() <= 1e-4 * pdf.max(1e-3));
            counts[li as usize] += 1;
        }
        for li in 0..37 {
            let expect = tree.probability(li as u32, p, n) * m as f32;
            assert!(
                (counts[li] as f32 - expect).abs() <= 3.0 + 0.02 * expect,
                "{li}: {} vs {expect}",
                counts[li]
            );
        }
        // Below every light, facing down: nothing can be reached.
        assert!(
            tree.pick(Vec3::new(0.0, -5.0, 0.0), Vec3::NEG_Y, 0.5)
                .is_none()
        );
    }
}
