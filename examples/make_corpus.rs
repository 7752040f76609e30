//! Makes the real-scene corpus in `assets/corpus/` from the architectural house model of
//! Debian's `assimp-testmodels` package (`IFC/AC14-FZK-Haus.ifc`, by KIT/IAI), converted with
//! `assimp export` (Debian `assimp-utils`):
//!
//! ```text
//! apt-get install assimp-utils assimp-testmodels
//! cargo run --release --example make_corpus            # writes assets/corpus/house.gltf
//! cargo run --release --example make_corpus -- IFC DIR
//! ```
//!
//! The house comes without lights; this adds a sun and a sky (a summer afternoon, through the
//! windows), and a point light in each of three rooms, and drops the glazing (its glass is a
//! translucent material the baker would treat as an opaque wall, so no daylight would enter).
//! The result is written with lightbake's own glTF writer, lights as `KHR_lights_punctual`
//! and the sky and the sun's angular radius as lightbake extras. Nothing else is changed: the
//! geometry, its units (metres) and its materials are the converter's.

use std::path::{Path, PathBuf};
use std::process::Command;

use glam::Vec3;
use lightbake::scene::gltf_write::write_scene_gltf;
use lightbake::scene::{Light, LightBake, LightKind, Scene};
use lightbake::{LightConvention, import_gltf};

/// Where Debian's `assimp-testmodels` puts the house.
const HOUSE_IFC: &str = "/usr/share/assimp/models/IFC/AC14-FZK-Haus.ifc";

fn main() -> Result<(), String> {
    let mut args = std::env::args().skip(1);
    let ifc = args
        .next()
        .map_or_else(|| PathBuf::from(HOUSE_IFC), PathBuf::from);
    let dir = args
        .next()
        .map_or_else(|| PathBuf::from("assets/corpus"), PathBuf::from);
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let glb = std::env::temp_dir().join(format!("lightbake-house-{}.glb", std::process::id()));
    convert(&ifc, &glb)?;
    let imported = import_gltf(&glb, LightConvention::GltfSpec).map_err(|e| e.to_string());
    let _ = std::fs::remove_file(&glb);
    let mut scene = imported?.scene;
    let dropped = drop_glazing(&mut scene);
    light_the_house(&mut scene);
    scene.name = "house".into();
    let path = dir.join("house.gltf");
    write_scene_gltf(&scene, &path).map_err(|e| e.to_string())?;
    let (lo, hi) = bounds(&scene);
    println!(
        "wrote {}: {} meshes, {} instances, {} triangles, {} lights; dropped {dropped} glazing instance(s); bounds {lo:.2} .. {hi:.2} m",
        path.display(),
        scene.meshes.len(),
        scene.instances.len(),
        scene.instanced_triangle_count(),
        scene.lights.len()
    );
    Ok(())
}

/// `assimp export IFC GLB`.
fn convert(ifc: &Path, glb: &Path) -> Result<(), String> {
    if !ifc.exists() {
        return Err(format!(
            "{} not found: install Debian's assimp-testmodels (apt-get install assimp-testmodels) or give the IFC file's path",
            ifc.display()
        ));
    }
    let status = Command::new("assimp")
        .arg("export")
        .arg(ifc)
        .arg(glb)
        .status()
        .map_err(|e| {
            format!("could not run assimp ({e}): install Debian's assimp-utils (apt-get install assimp-utils)")
        })?;
    if !status.success() {
        return Err(format!("assimp export {} failed: {status}", ifc.display()));
    }
    Ok(())
}

/// Removes the instances whose material is mostly transparent (alpha below 0.5: the window
/// glass). Returns how many.
fn drop_glazing(scene: &mut Scene) -> usize {
    let before = scene.instances.len();
    let transparent: Vec<bool> = scene
        .meshes
        .iter()
        .map(|m| {
            m.material
                .and_then(|k| scene.materials.get(k))
                .is_some_and(|mat| mat.base_color.w < 0.5)
        })
        .collect();
    scene.instances.retain(|i| !transparent[i.mesh]);
    before - scene.instances.len()
}

/// The scene's bounding box, m.
fn bounds(scene: &Scene) -> (Vec3, Vec3) {
    let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
    for inst in &scene.instances {
        for &p in &scene.meshes[inst.mesh].positions {
            let w = inst.transform.transform_point3(p);
            lo = lo.min(w);
            hi = hi.max(w);
        }
    }
    (lo, hi)
}

/// A summer-afternoon sun and sky, and a warm point light in three of the rooms (the model
/// is 12 m × 10 m, two storeys, Y up after conversion).
fn light_the_house(scene: &mut Scene) {
    // Sky luminance (nits, linear RGB) and a sun of 80 000 lux from 40° above the horizon.
    scene.sky = Vec3::new(1800.0, 2250.0, 3000.0);
    let elevation = 40f32.to_radians();
    let azimuth = 215f32.to_radians();
    let towards_sun = Vec3::new(
        elevation.cos() * azimuth.sin(),
        elevation.sin(),
        elevation.cos() * azimuth.cos(),
    );
    scene.lights.push(Light {
        name: "sun".into(),
        kind: LightKind::Directional {
            angular_radius: 0.00465,
        },
        color: Vec3::new(1.0, 0.95, 0.88),
        intensity: 80_000.0,
        range: None,
        position: Vec3::ZERO,
        direction: -towards_sun,
        bake: LightBake::Full,
    });
    // Lamps 0.4 m under the ceilings of three rooms: the ground floor spans y 0.2–2.7 m,
    // the upper floor starts at 2.9 m; the footprint is x 0–12 m, z −10–0 m.
    for (name, p) in [
        ("living room lamp", Vec3::new(3.0, 2.3, -3.0)),
        ("kitchen lamp", Vec3::new(9.0, 2.3, -7.5)),
        ("upstairs lamp", Vec3::new(6.0, 4.9, -5.0)),
    ] {
        scene.lights.push(Light {
            name: name.into(),
            kind: LightKind::Point,
            color: Vec3::new(1.0, 0.85, 0.7),
            // Candela: about a 1 500 lm bulb (1500 / 4π).
            intensity: 120.0,
            range: None,
            position: p,
            direction: Vec3::NEG_Z,
            bake: LightBake::Full,
        });
    }
}
