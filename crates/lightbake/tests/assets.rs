//! The shipped scenes in `assets/` (and the generated office of the corpus) are exactly what
//! `cargo run --example make_assets` writes from `lightbake::scene::testscenes`, and they
//! import cleanly.

use std::path::Path;

use lightbake::scene::gltf_import::import_gltf;
use lightbake::scene::gltf_write::scene_to_gltf;
use lightbake::scene::testscenes::{CornellLight, cornell_box, office_level, sunlit_room};
use lightbake::settings::LightConvention;

#[test]
fn committed_assets_match_their_generators() {
    let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets");
    for (scene, stem) in [
        (cornell_box(CornellLight::Area), "cornell_box"),
        (cornell_box(CornellLight::Point), "cornell_box_point"),
        (sunlit_room(), "sunlit_room"),
        (office_level(8, 6), "corpus/office"),
    ] {
        let file_name = stem.rsplit('/').next().expect("a file name");
        let (json, bin) = scene_to_gltf(&scene, &format!("{file_name}.bin"));
        let gltf_path = assets.join(format!("{stem}.gltf"));
        let on_disk = std::fs::read(&gltf_path).unwrap();
        assert!(
            on_disk == json && std::fs::read(assets.join(format!("{stem}.bin"))).unwrap() == bin,
            "{} is stale: run `cargo run --example make_assets`",
            gltf_path.display()
        );
        let imported = import_gltf(&gltf_path, LightConvention::GltfSpec).unwrap();
        assert!(
            imported.scene.warnings.is_empty(),
            "{:?}",
            imported.scene.warnings
        );
        assert_eq!(imported.scene.instances.len(), scene.instances.len());
    }
}
