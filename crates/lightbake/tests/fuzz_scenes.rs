//! Property-based search for non-finite values (proptest): random furnished rooms of the
//! kind that wrote NaN texels on a real kitchen — thin boards, panels lying flush on boards'
//! fronts, boards meeting at hard edges and boards passing through each other, albedo up to
//! 0.99, a point light anywhere (inside a board, on a face, a millimetre from one), densities
//! from a few texels per board to many — baked at preview and medium. Every bake must succeed
//! (a non-finite value stops a bake with the stage named, so a failure here names it), every
//! texel must be finite, and so must every number of the report (denoiser and stitch
//! statistics, error estimates).
//!
//! Bounded for CI: 12 cases from a fixed seed (about a minute); set `PROPTEST_CASES` and
//! `PROPTEST_RNG_SEED=random` for a longer search.

mod common;

use common::{add, bake};
use glam::{Affine3A, Quat, Vec3};
use lightbake::scene::testscenes::cuboid;
use lightbake::scene::{Light, LightBake, LightKind, Scene};
use lightbake::settings::BakeSettings;
use proptest::prelude::*;

/// How a board is placed.
#[derive(Clone, Copy, Debug)]
enum Place {
    /// Free in the room.
    Free,
    /// Lying flush on the front (+Z face) of the board before it, like a door panel.
    OnFront,
    /// Meeting the board before it along its top edge, at right angles.
    AtEdge,
    /// Passing through the board before it.
    Through,
}

#[derive(Clone, Debug)]
struct Board {
    place: Place,
    size: Vec3,
    at: Vec3,
    turn: f32,
    albedo: f32,
}

#[derive(Clone, Debug)]
struct Case {
    boards: Vec<Board>,
    light: Vec3,
    /// The light on a board's face (its index) or a millimetre off it, instead of `light`.
    on_board: Option<(usize, f32)>,
    intensity: f32,
    density: f32,
    medium: bool,
}

fn board() -> impl Strategy<Value = Board> {
    let thin = prop_oneof![Just(0.002f32), Just(0.01), Just(0.02), Just(0.05)];
    (
        prop_oneof![
            Just(Place::Free),
            Just(Place::OnFront),
            Just(Place::AtEdge),
            Just(Place::Through)
        ],
        (0.1f32..1.5, 0.1f32..1.5, thin),
        (0.3f32..3.7, 0.0f32..2.0, 0.3f32..2.7),
        prop_oneof![Just(0.0f32), Just(std::f32::consts::FRAC_PI_2), 0.0f32..6.3],
        prop_oneof![Just(0.99f32), 0.0f32..0.95],
    )
        .prop_map(|(place, (w, h, t), (x, y, z), turn, albedo)| Board {
            place,
            size: Vec3::new(w, h, t),
            at: Vec3::new(x, y, z),
            turn,
            albedo,
        })
}

fn case() -> impl Strategy<Value = Case> {
    (
        prop::collection::vec(board(), 1..7),
        (0.2f32..3.8, 0.1f32..2.5, 0.2f32..2.8),
        prop::option::of((0usize..7, prop_oneof![Just(0.0f32), Just(0.001)])),
        prop_oneof![Just(1.0f32), Just(50.0), Just(2000.0)],
        prop_oneof![Just(4.0f32), Just(16.0), Just(48.0)],
        any::<bool>(),
    )
        .prop_map(
            |(boards, (x, y, z), on_board, intensity, density, medium)| Case {
                boards,
                light: Vec3::new(x, y, z),
                on_board,
                intensity,
                density,
                medium,
            },
        )
}

/// The room (4 × 2.6 × 3 m, faces inward) and the boards, each an instance of a box whose
/// local frame has its front at +Z; a board placed against the one before it takes that
/// board's frame.
fn scene(c: &Case) -> (Scene, Vec3) {
    let mut s = Scene {
        name: "furnished".into(),
        ..Scene::default()
    };
    let mut room = cuboid("room", Vec3::ZERO, Vec3::new(4.0, 2.6, 3.0), false);
    for t in room.indices.chunks_exact_mut(3) {
        t.swap(1, 2);
    }
    for n in &mut room.normals {
        *n = -*n;
    }
    add(&mut s, room, Vec3::splat(0.7), Affine3A::IDENTITY, true);
    let mut frames: Vec<(Affine3A, Vec3)> = Vec::new();
    for (k, b) in c.boards.iter().enumerate() {
        let local = match (b.place, frames.last()) {
            (Place::OnFront, Some(&(prev, size))) => {
                // Flush on the front face, inset from its edges by a tenth.
                prev * Affine3A::from_translation(Vec3::new(0.1 * size.x, 0.1 * size.y, size.z))
            }
            (Place::AtEdge, Some(&(prev, size))) => {
                prev * Affine3A::from_translation(Vec3::new(0.0, size.y, 0.0))
                    * Affine3A::from_rotation_x(-std::f32::consts::FRAC_PI_2)
            }
            (Place::Through, Some(&(prev, size))) => {
                prev * Affine3A::from_translation(0.5 * size - 0.5 * b.size)
                    * Affine3A::from_rotation_y(0.7)
            }
            _ => Affine3A::from_rotation_translation(Quat::from_rotation_y(b.turn), b.at),
        };
        let size = match b.place {
            Place::OnFront if !frames.is_empty() => {
                let prev = frames.last().unwrap().1;
                Vec3::new(0.8 * prev.x, 0.8 * prev.y, b.size.z)
            }
            _ => b.size,
        };
        let mesh = cuboid(&format!("board{k}"), Vec3::ZERO, size, false);
        add(&mut s, mesh, Vec3::splat(b.albedo), local, true);
        frames.push((local, size));
    }
    let light = match c.on_board {
        Some((k, off)) => {
            let (frame, size) = frames[k % frames.len()];
            frame.transform_point3(Vec3::new(0.5 * size.x, 0.5 * size.y, size.z + off))
        }
        None => c.light,
    };
    s.lights.push(Light {
        name: "lamp".into(),
        kind: LightKind::Point,
        color: Vec3::new(1.0, 0.8, 0.6),
        intensity: c.intensity,
        range: None,
        position: light,
        direction: Vec3::NEG_Y,
        bake: LightBake::Full,
    });
    (s, light)
}

/// The places a `{:?}` of the report would show a non-finite number.
fn non_finite_in(debug: &str) -> Option<usize> {
    ["NaN", "inf"]
        .iter()
        .flat_map(|bad| {
            [": ", "(", ", ", "["]
                .iter()
                .filter_map(move |before| debug.find(&format!("{before}{bad}")))
        })
        .min()
}

proptest! {
    #![proptest_config(common::proptest_config_cases(0x5ce1e, 12))]

    #[test]
    fn furnished_rooms_bake_to_finite_lightmaps_and_reports(c in case()) {
        let (scene, light) = scene(&c);
        let mut settings = if c.medium { BakeSettings::medium() } else { BakeSettings::preview() };
        settings.layout.texel_density = Some(c.density);
        settings.layout.texel_density_from_scene = false;
        let out = bake(&scene, &settings);
        for (k, page) in out.pages.iter().enumerate() {
            let bad = page.texels.iter().filter(|t| !t.is_finite()).count();
            prop_assert_eq!(bad, 0, "page {}: {} non-finite texels (light at {:?})", k, bad, light);
        }
        let report = format!("{:?}", out.report);
        if let Some(at) = non_finite_in(&report) {
            let from = at.saturating_sub(300);
            prop_assert!(false, "a non-finite number in the report: …{}…", &report[from..(at + 20).min(report.len())]);
        }
    }
}
