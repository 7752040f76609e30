//! Property-based fuzzing of the split bake's readers (proptest): `patches.bin` with random
//! 4-byte writes or cut short, and work units with random starts and ray estimates, must be
//! read back or refused, never panic; whatever passes the checks must be safe to use (every
//! footprint run and page entry in range, every unit's patches in range for any shard count
//! the units allow).
//!
//! Bounded for CI: 500 cases per property from a fixed seed; `PROPTEST_CASES` and
//! `PROPTEST_RNG_SEED=random` search further (as in `fuzz_import.rs`).

mod common;

use std::sync::OnceLock;

use lightbake::bake::shard::Units;
use lightbake::context::Prepared;
use lightbake::raster::Patches;
use lightbake::scene::testscenes::{CornellLight, cornell_box};
use lightbake::settings::BakeSettings;
use proptest::prelude::*;

/// The Cornell box prepared at 8 texels/m, and its patches as bytes.
fn prepared() -> &'static (Prepared, Vec<u8>) {
    static P: OnceLock<(Prepared, Vec<u8>)> = OnceLock::new();
    P.get_or_init(|| {
        let mut s = BakeSettings::preview();
        s.layout.texel_density = Some(8.0);
        s.layout.texel_density_from_scene = false;
        let p = Prepared::new(&cornell_box(CornellLight::Area), &s).unwrap();
        let bytes = p.patches.to_bytes();
        (p, bytes)
    })
}

/// Reads `bytes` as the split bake does and, when the checks pass, touches every index.
fn read_and_use(bytes: &[u8]) {
    let (p, _) = prepared();
    let Some(patches) = Patches::from_bytes(bytes) else {
        return;
    };
    if patches
        .check(&p.layout, p.rays.triangles.len(), p.scene.instances.len())
        .is_err()
    {
        return;
    }
    for patch in &patches.patches {
        let _ = patches.footprint_of(patch);
        let w = p.layout.pages[patch.page as usize].width;
        let _ = patches.page_index[patch.page as usize][(patch.y * w + patch.x) as usize];
        let _ = p.rays.triangles[patch.triangle as usize];
    }
}

#[test]
fn the_prepared_patches_pass_their_own_checks() {
    let (p, bytes) = prepared();
    let back = Patches::from_bytes(bytes).unwrap();
    back.check(&p.layout, p.rays.triangles.len(), p.scene.instances.len())
        .unwrap();
    assert!(
        back.check(
            &p.layout,
            p.rays.triangles.len() / 2,
            p.scene.instances.len()
        )
        .is_err(),
        "a scene with fewer triangles than the patches name is refused"
    );
}

proptest! {
    #![proptest_config(common::proptest_config(0x5b1d_bace))]

    #[test]
    fn written_patches_are_read_or_refused(
        writes in prop::collection::vec((any::<usize>(), any::<[u8; 4]>()), 1..12),
        cut in any::<Option<usize>>(),
    ) {
        let (_, bytes) = prepared();
        let mut bytes = bytes.clone();
        let len = bytes.len() - 3;
        for (at, w) in &writes {
            // Half of the writes land in the first kilobyte (the header and first patches).
            let at = if at % 2 == 0 { at % 1024.min(len) } else { at % len };
            bytes[at..at + 4].copy_from_slice(w);
        }
        if let Some(c) = cut {
            bytes.truncate(c % (bytes.len() + 1));
        }
        read_and_use(&bytes);
    }

    #[test]
    fn units_are_checked_before_use(
        starts in prop::collection::vec(any::<u32>(), 0..40),
        rays in prop::collection::vec(prop_oneof![any::<f64>(), 0.0..1e6f64], 0..40),
        patches in 0usize..5000,
        count in 1u32..64,
    ) {
        let units = Units { starts, rays, patches_hash: 0, layout_hash: 0, preparation: 1 };
        if units.check(patches).is_ok() && count as usize <= units.rays.len() {
            let owner = units.patch_shards(count);
            prop_assert_eq!(owner.len(), patches);
            prop_assert!(owner.iter().all(|&s| s < count));
            prop_assert_eq!(units.shard_rays(count).len(), count as usize);
        }
    }
}
