//! Two bakes of one scene compared where a viewer sees them, whatever their layouts: at
//! points spread over the baked surfaces (as `--verify` places them), each bake's lightmap
//! read where the GPU reads it. An incremental bake is checked so against a full bake of the
//! edited scene; two full bakes with other seeds give the noise floor.

// Measurement tools for the benchmarks, examples and tests (the `internals` feature); an
// embedding program's build has no use for them.
#![cfg_attr(not(feature = "internals"), allow(dead_code))]

use serde::Serialize;

use super::points::{ScorePoint, sample_bake, sample_surface};
use crate::bake::BakeOutput;
use crate::bvh::RayScene;
use crate::color::luminance;
use crate::scene::Scene;

/// How far one bake is from another at surface points.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Agreement {
    /// RMS of the difference of the luminance of E/π over the RMS of the second bake's.
    pub relative_rms: f64,
    /// The largest difference at a point over the RMS value.
    pub worst: f64,
    /// Points both bakes could be read at.
    pub points: usize,
}

/// `a` against `b`, two bakes of `scene`, at `count` surface points (numbers from `seed`).
pub fn agreement(
    scene: &Scene,
    a: &BakeOutput,
    b: &BakeOutput,
    count: usize,
    seed: u32,
) -> Agreement {
    let rays = RayScene::build(scene);
    let points = sample_surface(scene, &rays, count, seed, |_| true);
    let (mut diff, mut norm, mut worst, mut n) = (0.0f64, 0.0f64, 0.0f64, 0usize);
    let mut diffs = Vec::with_capacity(points.len());
    for sp in &points {
        let p = ScorePoint {
            instance: rays.triangles[sp.triangle as usize].instance,
            position: sp.position,
            normal: sp.geometric_normal,
            reference: glam::Vec3::ZERO,
            variance: 0.0,
        };
        let (Some(x), Some(y)) = (sample_bake(a, &p), sample_bake(b, &p)) else {
            continue;
        };
        let (x, y) = (luminance(x) as f64, luminance(y) as f64);
        diff += (x - y) * (x - y);
        norm += y * y;
        diffs.push((x - y).abs());
        n += 1;
    }
    if norm <= 0.0 {
        return Agreement {
            points: n,
            ..Agreement::default()
        };
    }
    let rms = (norm / n as f64).sqrt();
    for d in diffs {
        worst = worst.max(d / rms);
    }
    Agreement {
        relative_rms: (diff / norm).sqrt(),
        worst,
        points: n,
    }
}

/// The instances of `a` (baked into `after`) that `b` (baked into `before`) had, with the same
/// mesh, and that did not keep their rectangle or their mesh's lightmap UVs: the names of
/// what an incremental bake moved in the atlas, with the rectangles before and after. An
/// instance is the same one by its name and its occurrence among instances of that name.
pub fn moved_instances(
    (before, b): (&BakeOutput, &Scene),
    (after, a): (&BakeOutput, &Scene),
) -> Vec<String> {
    let mut moved = Vec::new();
    for (i, inst) in a.instances.iter().enumerate() {
        let nth = a.instances[..i]
            .iter()
            .filter(|o| o.name == inst.name)
            .count();
        let Some(j) = (b.instances.iter().enumerate())
            .filter(|(_, o)| o.name == inst.name)
            .nth(nth)
            .map(|(j, _)| j)
        else {
            continue;
        };
        let same_mesh = b.meshes[b.instances[j].mesh].positions == a.meshes[inst.mesh].positions;
        if !same_mesh || !inst.bake {
            continue;
        }
        fn uv(o: &BakeOutput, m: usize) -> Option<&Vec<glam::Vec2>> {
            o.layout.meshes[m].as_ref().map(|u| &u.uv1)
        }
        let (was, is) = (before.layout.instances[j], after.layout.instances[i]);
        if was != is || uv(before, b.instances[j].mesh) != uv(after, inst.mesh) {
            moved.push(format!("{} ({was:?} → {is:?})", inst.name));
        }
    }
    moved
}
