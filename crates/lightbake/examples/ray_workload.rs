//! Writes the ray-tracing benchmark workload (the 204 800-triangle Cornell box of
//! `benches/trace.rs`, 100 000 incoherent gather rays and 100 000 shadow rays towards the
//! ceiling light) as raw little-endian f32 files, and times our BVH on exactly those rays on
//! one thread, so `benches/embree_compare.py` can trace the same triangles and rays with
//! Embree 4 and print the ratio. With a glTF scene as the second argument the workload is that
//! scene's triangles (every instance), 100 000 gather rays from area-weighted surface points
//! and 100 000 shadow rays between two such points.
//!
//! ```text
//! cargo run --release -p lightbake --example ray_workload -- /tmp/rays
//! python3 crates/lightbake/benches/embree_compare.py /tmp/rays
//! cargo run --release -p lightbake --example ray_workload -- /tmp/office assets/corpus/office.gltf
//! python3 crates/lightbake/benches/embree_compare.py /tmp/office
//! ```
//!
//! Files: `triangles.f32` (9 floats per triangle: three vertices), `gather.f32` and
//! `shadow.f32` (7 floats per ray: origin, unit direction, tmax; ∞ for gather rays), and
//! `lightbake.json` with our rates and hit counts.

use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use lightbake::LightConvention;
use lightbake::bvh::workload::{BenchRay, cornell_workload, scene_workload};

const RAYS: usize = 100_000;
const REPEATS: usize = 20;

fn write_f32(path: &PathBuf, values: impl Iterator<Item = f32>) -> std::io::Result<()> {
    let mut bytes = Vec::new();
    for v in values {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    std::fs::File::create(path)?.write_all(&bytes)
}

fn rays_f32(rays: &[BenchRay]) -> impl Iterator<Item = f32> + '_ {
    rays.iter().flat_map(|r| {
        [
            r.origin.x,
            r.origin.y,
            r.origin.z,
            r.direction.x,
            r.direction.y,
            r.direction.z,
            r.tmax,
        ]
    })
}

/// Best of `REPEATS` single-thread passes: (rays per second, hits).
fn best(f: impl Fn() -> usize) -> (f64, usize) {
    let mut rate: f64 = 0.0;
    let mut hits = 0;
    for _ in 0..REPEATS {
        let start = Instant::now();
        hits = f();
        rate = rate.max(RAYS as f64 / start.elapsed().as_secs_f64());
    }
    (rate, hits)
}

fn main() -> std::io::Result<()> {
    let dir = PathBuf::from(
        std::env::args()
            .nth(1)
            .unwrap_or_else(|| "ray_workload".into()),
    );
    std::fs::create_dir_all(&dir)?;
    let (rs, gather, shadow) = match std::env::args().nth(2) {
        Some(scene) => {
            let imported = lightbake::import_gltf(scene.as_ref(), LightConvention::GltfSpec)
                .map_err(|e| std::io::Error::other(format!("{scene}: {e}")))?;
            scene_workload(&imported.scene, RAYS)
        }
        None => cornell_workload(RAYS),
    };
    let (nodes, packets, bytes) = rs.bvh_size();
    println!(
        "BVH build {:.3} s (single thread): {nodes} nodes, {packets} leaf packets, {:.1} MiB",
        rs.build_time.as_secs_f64(),
        bytes as f64 / 1048576.0
    );
    let n = rs.triangles.len() as u32;
    write_f32(
        &dir.join("triangles.f32"),
        (0..n).flat_map(|g| {
            rs.triangle_vertices(g)
                .into_iter()
                .flat_map(|v| [v.x, v.y, v.z])
        }),
    )?;
    write_f32(&dir.join("gather.f32"), rays_f32(&gather))?;
    write_f32(&dir.join("shadow.f32"), rays_f32(&shadow))?;

    let (closest, closest_hits) = best(|| {
        gather
            .iter()
            .filter(|r| rs.closest_hit(r.origin, r.direction, 0.0, r.tmax).is_some())
            .count()
    });
    let (any, occluded) = best(|| {
        shadow
            .iter()
            .filter(|r| rs.occluded(r.origin, r.direction, 0.0, r.tmax))
            .count()
    });
    let json = format!(
        "{{\"triangles\": {n}, \"rays\": {RAYS}, \"closest_per_second\": {closest:.1}, \"closest_hits\": {closest_hits}, \"shadow_per_second\": {any:.1}, \"shadow_occluded\": {occluded}}}\n"
    );
    std::fs::write(dir.join("lightbake.json"), &json)?;
    println!(
        "{n} triangles; one thread, best of {REPEATS}: closest hit {:.3} Mrays/s ({closest_hits} hits), any hit {:.3} Mrays/s ({occluded} occluded)",
        closest / 1e6,
        any / 1e6
    );
    println!("wrote {}", dir.display());
    Ok(())
}
