//! Shows a glTF baked by the `bake` command, with its lightmaps, and picks up re-bakes live.
//!
//! ```text
//! cargo run --release -p lightbake-cli -- assets/cornell_box.gltf -o baked/cornell_box
//! cargo run --release --example view_baked -- baked/cornell_box/cornell_box.gltf
//! cargo run --release --example view_baked -- baked/cornell_box/cornell_box.gltf --screenshot view.png
//! ```
//!
//! The baked glTF's folder is the asset root and Bevy's file watcher is on: run the `bake`
//! command again into the same folder (other settings, same scene) and the new lightmaps
//! appear without a restart. The camera frames the scene from its front (+Z), or stands where
//! `--camera EYE_X,EYE_Y,EYE_Z,AT_X,AT_Y,AT_Z` says, at `--ev100 EV` (default 6). `Space` switches between the lightmaps
//! and Bevy's real-time lighting of the glTF's lights.
//!
//! A scene baked with light groups (`bake --group NAME=light,...`) starts at the weights
//! `--weights NAME=W,NAME=W` gives (1 for the others); keys `1`–`9` switch the groups in the
//! order the bake lists them between weight 0 and 1.

#[path = "support/mod.rs"]
mod support;

use std::path::{Path, PathBuf};

use bevy::camera::primitives::Aabb;
use bevy::camera::{Exposure, RenderTarget};
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::light::GlobalAmbientLight;
use bevy::pbr::Lightmap;
use bevy::prelude::*;
use bevy::world_serialization::WorldInstanceReady;
use bevy_lightbake::capture::FrameCapture;
use bevy_lightbake::groups::{GroupSums, SummedPage};
use bevy_lightbake::prelude::*;

#[derive(Resource)]
struct Viewer {
    gltf: String,
    target: Option<Handle<Image>>,
    framed: bool,
    /// `--camera`: eye and the point it looks at.
    camera: Option<(Vec3, Vec3)>,
}

/// `--weights NAME=W,...`.
fn weights_arg() -> LightGroupWeights {
    let mut weights = LightGroupWeights::default();
    for pair in support::option_arg("--weights")
        .unwrap_or_default()
        .split(',')
    {
        if let Some((name, w)) = pair.split_once('=') {
            let w: f32 = w
                .trim()
                .parse()
                .expect("--weights NAME=W,...: W is a number");
            weights.set(name.trim(), w);
        }
    }
    weights
}

/// `--camera EYE_X,EYE_Y,EYE_Z,AT_X,AT_Y,AT_Z`.
fn camera_arg() -> Option<(Vec3, Vec3)> {
    let v: Vec<f32> = (support::option_arg("--camera")?.split(','))
        .map(|x| x.trim().parse().expect("--camera takes six numbers"))
        .collect();
    assert_eq!(v.len(), 6, "--camera takes six numbers");
    Some((Vec3::new(v[0], v[1], v[2]), Vec3::new(v[3], v[4], v[5])))
}

fn main() -> AppExit {
    let screenshot = support::screenshot_arg();
    let path = PathBuf::from(
        support::positional_arg().unwrap_or_else(|| "baked/cornell_box/cornell_box.gltf".into()),
    );
    let path = std::path::absolute(&path).unwrap_or(path);
    if !path.exists() {
        eprintln!(
            "{} does not exist; bake it first:\n  cargo run --release -p lightbake-cli -- assets/cornell_box.gltf -o baked/cornell_box",
            path.display()
        );
        return AppExit::error();
    }
    let folder = path.parent().unwrap_or(Path::new(".")).to_path_buf();
    let file = path
        .file_name()
        .unwrap_or_default()
        .to_string_lossy()
        .into_owned();
    let mut app = App::new();
    app.add_plugins(support::default_plugins(screenshot.is_some(), &folder))
        .add_plugins(LightbakePlugin)
        // Everything the lightmaps show was baked; Bevy's default ambient would add to it.
        .insert_resource(GlobalAmbientLight::NONE);
    let target = screenshot.map(|p| support::add_capture(&mut app, 640, 480, Some(p)));
    app.insert_resource(Viewer {
        gltf: file,
        target,
        framed: false,
        camera: camera_arg(),
    })
    .insert_resource(weights_arg())
    .add_systems(Startup, setup)
    .add_systems(Update, (toggle, switch_groups, arm_capture));
    app.run()
}

fn setup(mut commands: Commands, server: Res<AssetServer>, viewer: Res<Viewer>) {
    commands
        .spawn(WorldAssetRoot(server.load(
            GltfAssetLabel::Scene(0).from_asset(viewer.gltf.clone()),
        )))
        .observe(frame_scene);
}

/// Places a camera in front of the scene once it has spawned.
fn frame_scene(
    ready: On<WorldInstanceReady>,
    children: Query<&Children>,
    boxes: Query<(&Aabb, &GlobalTransform)>,
    mut commands: Commands,
    mut viewer: ResMut<Viewer>,
) {
    if viewer.framed {
        return;
    }
    viewer.framed = true;
    let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
    for e in children.iter_descendants(ready.entity) {
        if let Ok((aabb, t)) = boxes.get(e) {
            for corner in [aabb.min(), aabb.max()] {
                let p = t.transform_point(Vec3::from(corner));
                lo = lo.min(p);
                hi = hi.max(p);
            }
        }
    }
    if lo.x > hi.x {
        (lo, hi) = (Vec3::splat(-1.0), Vec3::splat(1.0));
    }
    let centre = (lo + hi) / 2.0;
    let size = (hi - lo).max_element();
    let (eye, at) = viewer.camera.unwrap_or((
        centre + Vec3::new(0.0, 0.0, hi.z - centre.z + 1.3 * size),
        centre,
    ));
    let mut camera = commands.spawn((
        Camera3d::default(),
        Transform::from_translation(eye).looking_at(at, Vec3::Y),
        Exposure {
            ev100: support::option_arg("--ev100")
                .map_or(6.0, |v| v.parse().expect("--ev100 takes a number")),
        },
    ));
    if let Some(image) = &viewer.target {
        // No camera draws to a window: this one places the shadow maps' detail.
        camera.insert((
            RenderTarget::Image(image.clone().into()),
            Tonemapping::None,
            bevy::core_pipeline::tonemapping::DebandDither::Disabled,
            bevy::camera::ShadowLodOrigin,
        ));
    }
}

fn toggle(input: Option<Res<ButtonInput<KeyCode>>>, mut show: ResMut<ShowLightmaps>) {
    if input.is_some_and(|i| i.just_pressed(KeyCode::Space)) {
        show.0 = !show.0;
    }
}

/// Keys `1`–`9`: group k of the first summed page between weight 0 and 1.
fn switch_groups(
    input: Option<Res<ButtonInput<KeyCode>>>,
    sums: Res<GroupSums>,
    pages: Query<&SummedPage>,
    mut weights: ResMut<LightGroupWeights>,
) {
    let (Some(input), Some(page)) = (input, pages.iter().next()) else {
        return;
    };
    let keys = [
        KeyCode::Digit1,
        KeyCode::Digit2,
        KeyCode::Digit3,
        KeyCode::Digit4,
        KeyCode::Digit5,
        KeyCode::Digit6,
        KeyCode::Digit7,
        KeyCode::Digit8,
        KeyCode::Digit9,
    ];
    for ((group, _), key) in sums.sources(&page.0).into_iter().zip(keys) {
        if input.just_pressed(key) {
            let w = if weights.get(&group) > 0.0 { 0.0 } else { 1.0 };
            info!("light group {group}: weight {w}");
            weights.set(group, w);
        }
    }
}

fn arm_capture(
    capture: Option<ResMut<FrameCapture>>,
    viewer: Res<Viewer>,
    shown: Query<(&Lightmapped, Option<&Lightmap>, Option<&SummedPage>)>,
    sums: Res<GroupSums>,
) {
    // Every lightmap shown; with light groups, every page's sum at the weights asked for.
    let summed = sums.pages() == 0 || sums.applied();
    if let Some(mut capture) = capture
        && viewer.framed
        && !shown.is_empty()
        && summed
        && shown
            .iter()
            .all(|(l, m, page)| l.is_shown_by(m) && page.is_none_or(|p| sums.shows_sum(p, l)))
    {
        capture.armed = true;
    }
}
