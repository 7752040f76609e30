//! Regenerates the shipped scenes in `assets/` (and the generated scene of the corpus,
//! `assets/corpus/office.gltf`) from the code in `lightbake::scene::testscenes`:
//!
//! ```text
//! cargo run --example make_assets            # writes into ./assets
//! cargo run --example make_assets -- DIR     # writes into DIR
//! ```
//!
//! `crates/lightbake/tests/assets.rs` fails when the committed files differ from what this writes.

use std::path::PathBuf;

use lightbake::scene::gltf_write::write_scene_gltf;
use lightbake::scene::testscenes::{CornellLight, cornell_box, office_level, sunlit_room};

fn main() -> lightbake::Result<()> {
    let dir = std::env::args()
        .nth(1)
        .map_or_else(|| PathBuf::from("assets"), PathBuf::from);
    for (scene, file) in [
        (cornell_box(CornellLight::Area), "cornell_box.gltf"),
        (cornell_box(CornellLight::Point), "cornell_box_point.gltf"),
        (sunlit_room(), "sunlit_room.gltf"),
        (office_level(8, 6), "corpus/office.gltf"),
    ] {
        let path = dir.join(file);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).map_err(|source| lightbake::BakeError::Write {
                path: parent.to_path_buf(),
                source,
            })?;
        }
        write_scene_gltf(&scene, &path)?;
        println!("wrote {}", path.display());
    }
    Ok(())
}
