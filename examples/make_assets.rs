//! Regenerates the shipped scenes in `assets/` from the code in
//! `lightbake::scene::testscenes`:
//!
//! ```text
//! cargo run --example make_assets            # writes into ./assets
//! cargo run --example make_assets -- DIR     # writes into DIR
//! ```
//!
//! `crates/lightbake/tests/assets.rs` fails when the committed files differ from what this writes.

use std::path::PathBuf;

use lightbake::scene::gltf_write::write_scene_gltf;
use lightbake::scene::testscenes::{CornellLight, cornell_box, sunlit_room};

fn main() -> lightbake::Result<()> {
    let dir = std::env::args()
        .nth(1)
        .map_or_else(|| PathBuf::from("assets"), PathBuf::from);
    for (scene, file) in [
        (cornell_box(CornellLight::Area), "cornell_box.gltf"),
        (cornell_box(CornellLight::Point), "cornell_box_point.gltf"),
        (sunlit_room(), "sunlit_room.gltf"),
    ] {
        let path = dir.join(file);
        write_scene_gltf(&scene, &path)?;
        println!("wrote {}", path.display());
    }
    Ok(())
}
