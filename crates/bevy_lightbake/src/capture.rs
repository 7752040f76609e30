//! Headless frame capture: render a camera into an image, read it back, and keep the first
//! frame that is *settled* — every render pipeline compiled and the picture unchanged over a
//! few read-backs. Software renderers (Mesa's lavapipe) compile pipelines for many frames;
//! counting frames is not enough, so this waits for the pipeline cache to be empty instead.
//! A render pipeline that failed to build (a shader that does not compile for a mesh's
//! attributes draws nothing of that mesh) fails the capture, naming the error, rather than
//! giving a frame with the mesh silently missing.
//!
//! Used by the examples' `--screenshot PATH` and by the render tests.

use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

use bevy::asset::RenderAssetUsages;
use bevy::prelude::*;
use bevy::render::gpu_readback::{Readback, ReadbackComplete};
use bevy::render::render_resource::{
    CachedPipelineState, Extent3d, PipelineCache, TextureDimension, TextureFormat, TextureUsages,
};
use bevy::render::{Render, RenderApp, RenderSystems};
use bevy::shader::ShaderCacheError;

/// Read-back frames, 8-bit sRGB RGBA, rows top to bottom.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CapturedFrame {
    /// Pixels across.
    pub width: u32,
    /// Pixels down.
    pub height: u32,
    /// `width × height × 4` bytes.
    pub rgba: Vec<u8>,
}

impl CapturedFrame {
    /// The pixel at (x, y) as linear RGB in [0, 1] (sRGB decoded).
    pub fn linear(&self, x: u32, y: u32) -> Vec3 {
        let i = ((y * self.width + x) * 4) as usize;
        let d = |v: u8| Color::srgb_u8(v, 0, 0).to_linear().red;
        Vec3::new(d(self.rgba[i]), d(self.rgba[i + 1]), d(self.rgba[i + 2]))
    }

    /// Mean linear RGB over the pixel rectangle [x0, x1) × [y0, y1).
    pub fn mean_linear(&self, x0: u32, y0: u32, x1: u32, y1: u32) -> Vec3 {
        let mut sum = Vec3::ZERO;
        for y in y0..y1 {
            for x in x0..x1 {
                sum += self.linear(x, y);
            }
        }
        sum / ((x1 - x0) * (y1 - y0)).max(1) as f32
    }

    /// Writes a PNG.
    ///
    /// # Errors
    /// [`SaveError`] naming the folder or file that cannot be written.
    pub fn save_png(&self, path: &std::path::Path) -> Result<(), SaveError> {
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir).map_err(|source| SaveError::Folder {
                path: dir.to_path_buf(),
                source,
            })?;
        }
        image::save_buffer(
            path,
            &self.rgba,
            self.width,
            self.height,
            image::ExtendedColorType::Rgba8,
        )
        .map_err(|source| SaveError::Png {
            path: path.to_path_buf(),
            source,
        })
    }
}

/// Why a captured frame could not be written.
#[derive(Debug, thiserror::Error)]
pub enum SaveError {
    /// The folder could not be made.
    #[error("{}: {source}", path.display())]
    Folder {
        /// The folder.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The PNG could not be encoded or written.
    #[error("{}: {source}", path.display())]
    Png {
        /// The file.
        path: PathBuf,
        /// Why.
        source: image::ImageError,
    },
}

/// Drives a capture. Insert with [`FrameCapture::new`], render a camera into
/// [`FrameCapture::target`], set [`FrameCapture::armed`] when the scene is complete, and read
/// [`FrameCapture::frame`] once [`FrameCapture::done`].
#[derive(Resource, Debug)]
pub struct FrameCapture {
    /// The render target (`Rgba8UnormSrgb`, readable).
    pub target: Handle<Image>,
    /// Target size in pixels.
    pub size: UVec2,
    /// The app says the scene is complete (bakes finished, lightmaps attached); settled frames
    /// are only counted from then on. Default `false`.
    pub armed: bool,
    /// Consecutive identical read-backs (with no pipeline compiling) that make a frame
    /// settled. Default 4.
    pub settle_readbacks: u32,
    /// Give up after this many read-backs once armed. Default 3000.
    pub max_readbacks: u32,
    /// Where to save the settled frame as PNG, if anywhere.
    pub save_to: Option<PathBuf>,
    /// Write `AppExit` once the frame is settled (or the capture gave up). Default `false`.
    pub exit_when_done: bool,
    /// The settled frame.
    pub frame: Option<CapturedFrame>,
    /// Set when the capture gave up, with the reason.
    pub failed: Option<String>,
    /// Render pipelines still compiling at the last read-back (diagnostics).
    pub pipelines_compiling: usize,
    /// Read-backs seen since the capture was armed (diagnostics).
    pub readbacks: u32,
    /// The render pipelines that failed to build at the last read-back, one error each. A
    /// frame that settles with any fails the capture.
    pub pipeline_errors: Vec<String>,
    latest: Option<Vec<u8>>,
    previous: Option<Vec<u8>>,
    fresh: bool,
    same: u32,
}

impl FrameCapture {
    /// A capture of `width × height` pixels; adds its render target to `images`.
    pub fn new(width: u32, height: u32, images: &mut Assets<Image>) -> Self {
        let mut target = Image::new_fill(
            Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            TextureDimension::D2,
            &[0, 0, 0, 255],
            TextureFormat::Rgba8UnormSrgb,
            RenderAssetUsages::default(),
        );
        target.texture_descriptor.usage = TextureUsages::TEXTURE_BINDING
            | TextureUsages::COPY_DST
            | TextureUsages::COPY_SRC
            | TextureUsages::RENDER_ATTACHMENT;
        Self {
            target: images.add(target),
            size: UVec2::new(width, height),
            armed: false,
            settle_readbacks: 4,
            max_readbacks: 3000,
            save_to: None,
            exit_when_done: false,
            frame: None,
            failed: None,
            pipelines_compiling: 0,
            latest: None,
            previous: None,
            fresh: false,
            same: 0,
            readbacks: 0,
            pipeline_errors: Vec::new(),
        }
    }

    /// Whether a frame settled or the capture gave up.
    pub fn done(&self) -> bool {
        self.frame.is_some() || self.failed.is_some()
    }

    /// Forgets the captured frame and disarms, to capture the scene again once it changed
    /// (another bake): set [`Self::armed`] again when it is complete.
    pub fn rearm(&mut self) {
        self.armed = false;
        self.frame = None;
        self.failed = None;
        self.readbacks = 0;
        self.latest = None;
        self.previous = None;
        self.fresh = false;
        self.same = 0;
    }
}

/// Pipelines the render world is still compiling, and the errors of those that failed,
/// shared with the main world.
#[derive(Resource, Clone, Default)]
struct PipelinesWaiting(Arc<AtomicUsize>, Arc<Mutex<Vec<String>>>);

/// Adds frame capture. Needs Bevy's `RenderPlugin` with a real device; the app inserts a
/// [`FrameCapture`].
pub struct FrameCapturePlugin;

impl Plugin for FrameCapturePlugin {
    fn build(&self, app: &mut App) {
        let waiting = PipelinesWaiting::default();
        app.insert_resource(waiting.clone())
            .add_systems(PostUpdate, (start_readback, settle_capture));
        if let Some(render_app) = app.get_sub_app_mut(RenderApp) {
            render_app
                .insert_resource(waiting)
                .add_systems(Render, count_waiting.after(RenderSystems::Render));
        }
    }
}

fn count_waiting(cache: Res<PipelineCache>, waiting: Res<PipelinesWaiting>) {
    waiting
        .0
        .store(cache.waiting_pipelines().count(), Ordering::Relaxed);
    // Not loaded yet is retried by the cache; the other errors are final.
    let failed = (cache.pipelines())
        .filter_map(|p| match &p.state {
            CachedPipelineState::Err(
                e @ (ShaderCacheError::ProcessShaderError(_)
                | ShaderCacheError::CreateShaderModule(_)),
            ) => Some(e.to_string()),
            _ => None,
        })
        .collect();
    if let Ok(mut errors) = waiting.1.lock() {
        *errors = failed;
    }
}

#[derive(Component)]
struct CaptureReadback;

fn start_readback(
    mut commands: Commands,
    capture: Option<Res<FrameCapture>>,
    existing: Query<(), With<CaptureReadback>>,
) {
    let Some(capture) = capture else {
        return;
    };
    if !existing.is_empty() || capture.done() {
        return;
    }
    commands
        .spawn((CaptureReadback, Readback::texture(capture.target.clone())))
        .observe(
            |ev: On<ReadbackComplete>, capture: Option<ResMut<FrameCapture>>| {
                if let Some(mut c) = capture {
                    c.latest = Some(ev.data.clone());
                    c.fresh = true;
                }
            },
        );
}

/// Removes the 256-byte row padding of a read-back.
fn unpad(data: &[u8], width: u32, height: u32) -> Option<Vec<u8>> {
    let row = width as usize * 4;
    let padded = row.div_ceil(256) * 256;
    let stride = if data.len() == row * height as usize {
        row
    } else {
        padded
    };
    if data.len() < stride * (height as usize - 1) + row {
        return None;
    }
    Some(
        (0..height as usize)
            .flat_map(|y| &data[y * stride..y * stride + row])
            .copied()
            .collect(),
    )
}

fn settle_capture(
    mut commands: Commands,
    capture: Option<ResMut<FrameCapture>>,
    waiting: Res<PipelinesWaiting>,
    readbacks: Query<Entity, With<CaptureReadback>>,
    mut exit: MessageWriter<AppExit>,
) {
    let Some(mut c) = capture else {
        return;
    };
    if c.done() || !c.fresh {
        return;
    }
    c.fresh = false;
    let Some(pixels) = c.latest.take().and_then(|d| unpad(&d, c.size.x, c.size.y)) else {
        return;
    };
    if !c.armed {
        return;
    }
    c.readbacks += 1;
    c.pipelines_compiling = waiting.0.load(Ordering::Relaxed);
    c.pipeline_errors = waiting.1.lock().map(|e| e.clone()).unwrap_or_default();
    let compiling = c.pipelines_compiling > 0;
    let same = c.previous.as_ref() == Some(&pixels);
    c.same = if same && !compiling { c.same + 1 } else { 0 };
    c.previous = Some(pixels.clone());
    if c.same >= c.settle_readbacks {
        let frame = CapturedFrame {
            width: c.size.x,
            height: c.size.y,
            rgba: pixels,
        };
        if let Some(path) = c.save_to.clone()
            && let Err(e) = frame.save_png(&path)
        {
            c.failed = Some(e.to_string());
        }
        if let Some(first) = c.pipeline_errors.first() {
            c.failed = Some(format!(
                "{} render pipeline(s) failed to build, so what they draw is missing from the frame; the first: {first}",
                c.pipeline_errors.len()
            ));
        }
        c.frame = Some(frame);
    } else if c.readbacks >= c.max_readbacks {
        c.failed = Some(format!(
            "the frame did not settle within {} read-backs ({} pipelines still compiling)",
            c.max_readbacks, c.pipelines_compiling
        ));
    }
    if c.done() {
        if let Some(reason) = &c.failed {
            error!("lightbake: the frame capture failed: {reason}");
        }
        for e in &readbacks {
            commands.entity(e).despawn();
        }
        if c.exit_when_done {
            exit.write(match &c.failed {
                None => AppExit::Success,
                Some(_) => AppExit::error(),
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unpadding_rows() {
        // 3 px wide: 12 bytes per row, padded to 256.
        let mut data = vec![0u8; 256 + 12];
        data[..12].copy_from_slice(&[1; 12]);
        data[256..].copy_from_slice(&[2; 12]);
        let out = unpad(&data, 3, 2).unwrap();
        assert_eq!(out.len(), 24);
        assert!(out[..12].iter().all(|&v| v == 1) && out[12..].iter().all(|&v| v == 2));
        assert_eq!(unpad(&[0; 10], 3, 2), None);
        // 64 px: rows are already 256 bytes.
        assert_eq!(unpad(&vec![7; 512], 64, 2).unwrap().len(), 512);
    }
}
