//! Lightmap pages as Bevy images.
//!
//! Bevy samples a lightmap with a filtering sampler, so its format must be filterable on every
//! backend: `Rgba16Float`. The baker writes half-float EXR, which Bevy's EXR loader expands
//! to `Rgba32Float` (filterable only where the device has `FLOAT32_FILTERABLE`); the plugin
//! narrows it back to `Rgba16Float`, losslessly, as soon as it loads. BC6H pages are loaded
//! instead where the GPU samples them ([`loads_bc6h`]).

use bevy::asset::RenderAssetUsages;
use bevy::prelude::*;
use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat};
use bevy::render::renderer::RenderDevice;
use bevy::render::settings::WgpuFeatures;
use half::f16;
use lightbake::lightmap::{HALF_MAX, LightmapPage, bilinear_taps};

use crate::components::LightbakeConfig;

/// A baked page as an `Rgba16Float` image (alpha 1), kept on the CPU as well so that games
/// and tests can read it.
pub fn page_image(page: &LightmapPage) -> Image {
    let mut data = Vec::with_capacity(page.texels.len() * 8);
    for t in &page.texels {
        for c in [t.x, t.y, t.z, 1.0] {
            data.extend_from_slice(&f16::from_f32(c.min(HALF_MAX)).to_le_bytes());
        }
    }
    Image::new(
        Extent3d {
            width: page.width,
            height: page.height,
            depth_or_array_layers: 1,
        },
        TextureDimension::D2,
        data,
        TextureFormat::Rgba16Float,
        RenderAssetUsages::default(),
    )
}

/// A baked irradiance volume as the `Rgba16Float` 3D image Bevy's `IrradianceVolume` reads
/// (its ambient-cube layout; see [`lightbake::probes::volume`]).
pub fn volume_image(volume: &lightbake::probes::IrradianceVolume) -> Image {
    let (size, texels) = volume.texture();
    let mut data = Vec::with_capacity(texels.len() * 8);
    for t in &texels {
        for c in [t.x, t.y, t.z, 1.0] {
            data.extend_from_slice(&f16::from_f32(c.min(HALF_MAX)).to_le_bytes());
        }
    }
    Image::new(
        Extent3d {
            width: size.x,
            height: size.y,
            depth_or_array_layers: size.z,
        },
        TextureDimension::D3,
        data,
        TextureFormat::Rgba16Float,
        RenderAssetUsages::default(),
    )
}

/// Whether Bevy can show `image` as a lightmap on any device as it is.
pub fn is_ready(image: &Image) -> bool {
    image.data.is_some() && image.texture_descriptor.format != TextureFormat::Rgba32Float
}

/// Narrows an `Rgba32Float` image to `Rgba16Float` in place. Returns whether it changed.
pub fn narrow_to_half(image: &mut Image) -> bool {
    if image.texture_descriptor.format != TextureFormat::Rgba32Float {
        return false;
    }
    let Some(data) = image.data.as_ref() else {
        return false;
    };
    let half: Vec<u8> = data
        .chunks_exact(4)
        .flat_map(|c| {
            let v = f32::from_le_bytes([c[0], c[1], c[2], c[3]]);
            f16::from_f32(v.min(HALF_MAX)).to_le_bytes()
        })
        .collect();
    image.data = Some(half);
    image.texture_descriptor.format = TextureFormat::Rgba16Float;
    true
}

/// Linear RGB of texel (x, y) of an `Rgba16Float` or `Rgba32Float` image, if in range.
pub fn texel(image: &Image, x: u32, y: u32) -> Option<Vec3> {
    let (w, h) = (image.width(), image.height());
    if x >= w || y >= h {
        return None;
    }
    let data = image.data.as_ref()?;
    let i = (y * w + x) as usize;
    match image.texture_descriptor.format {
        TextureFormat::Rgba16Float => {
            let c = |k: usize| {
                let o = i * 8 + k * 2;
                f16::from_le_bytes([data[o], data[o + 1]]).to_f32()
            };
            Some(Vec3::new(c(0), c(1), c(2)))
        }
        TextureFormat::Rgba32Float => {
            let c = |k: usize| {
                let o = i * 16 + k * 4;
                f32::from_le_bytes([data[o], data[o + 1], data[o + 2], data[o + 3]])
            };
            Some(Vec3::new(c(0), c(1), c(2)))
        }
        _ => None,
    }
}

/// Bilinear sample at `uv` ∈ [0, 1]² (texel centres at (x + ½)/W), clamped at the edges:
/// what Bevy's lightmap sampler returns (the core's [`bilinear_taps`]).
pub fn sample_bilinear(image: &Image, uv: Vec2) -> Option<Vec3> {
    bilinear_taps(image.width(), image.height(), uv.x, uv.y)
        .iter()
        .try_fold(Vec3::ZERO, |sum, &((x, y), w)| {
            Some(sum + texel(image, x, y)? * w)
        })
}

/// Whether a baked glTF's BC6H pages are loaded in place of its other pages:
/// [`LightbakeConfig::bc6h`] is set and the GPU samples BC textures.
pub fn loads_bc6h(config: &LightbakeConfig, device: Option<&RenderDevice>) -> bool {
    config.bc6h
        && device.is_some_and(|d| d.features().contains(WgpuFeatures::TEXTURE_COMPRESSION_BC))
}

#[cfg(test)]
mod tests {
    use super::*;
    use lightbake::glam::Vec3 as CoreVec3;

    #[test]
    fn page_round_trips_through_half_and_narrowing_is_lossless() {
        let mut page = LightmapPage::black(3, 2);
        for (i, t) in page.texels.iter_mut().enumerate() {
            *t = CoreVec3::new(i as f32 * 0.25, 1.0 / (i as f32 + 1.0), 70000.0);
        }
        let image = page_image(&page);
        assert!(is_ready(&image));
        for y in 0..2 {
            for x in 0..3 {
                let i = (y * 3 + x) as usize;
                let got = texel(&image, x, y).unwrap();
                let want = page.texels[i];
                assert!((got.x - want.x).abs() <= want.x * 1e-3, "{got} {want}");
                assert!((got.y - want.y).abs() <= want.y * 1e-3);
                assert_eq!(got.z, 65504.0, "clamped to the half maximum");
            }
        }
        // Widen to f32 as Bevy's EXR loader does, then narrow back: same bits.
        let mut wide = image.clone();
        let data: Vec<u8> = image
            .data
            .as_ref()
            .unwrap()
            .chunks_exact(2)
            .flat_map(|c| f16::from_le_bytes([c[0], c[1]]).to_f32().to_le_bytes())
            .collect();
        wide.data = Some(data);
        wide.texture_descriptor.format = TextureFormat::Rgba32Float;
        assert!(!is_ready(&wide));
        assert_eq!(texel(&wide, 2, 1), texel(&image, 2, 1));
        assert!(narrow_to_half(&mut wide));
        assert!(!narrow_to_half(&mut wide));
        assert_eq!(wide.data, image.data);
    }

    #[test]
    fn bilinear_sampling_hits_texel_centres_and_blends_between() {
        let mut page = LightmapPage::black(2, 1);
        page.texels[0] = CoreVec3::splat(1.0);
        page.texels[1] = CoreVec3::splat(3.0);
        let image = page_image(&page);
        let s = |u: f32| sample_bilinear(&image, Vec2::new(u, 0.5)).unwrap().x;
        assert_eq!(s(0.25), 1.0);
        assert_eq!(s(0.75), 3.0);
        assert_eq!(s(0.5), 2.0);
        assert_eq!(s(0.0), 1.0, "clamped at the edge");
    }
}
