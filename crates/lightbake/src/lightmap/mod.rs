//! Lightmap pages: patch values written into their texels, invalid texels filled from their
//! chart neighbours, and the padding dilated so bilinear and bicubic sampling never read an
//! unset texel.
//!
//! # What a texel stores
//! Irradiance over π, E/π, in Bevy's light units (lux/π), linear RGB. Bevy's PBR shader adds
//! `lightmap × lightmap_exposure × diffuse_color` (`pbr_functions.wesl`), and a Lambertian
//! surface of albedo ρ under irradiance E reflects radiance ρ·E/π; so with
//! `lightmap_exposure = 1` the game shows exactly the baked light. A white floor 1 m under a
//! 1 cd point light stores 1/π ≈ 0.318.

// The finishing steps take the stages' internal types (patches, rays): public with the
// `internals` feature; what the report holds of them is re-exported below.
internal!(
    assembly,
    contacts,
    denoise,
    grid_error,
    least_squares,
    seams,
    stitch
);

#[cfg(feature = "internals")]
pub use assembly::{AssembleStats, Assembly, TexelState, assemble};
#[cfg(not(feature = "internals"))]
pub(crate) use assembly::{Assembly, TexelState, assemble};

pub use contacts::ContactStats;
pub use denoise::DenoiseStats;
pub use seams::SeamJumps;
pub use stitch::{OpenSeam, OpenWhy, StitchStats};

use glam::{Vec2, Vec3};

use crate::raster::bilinear_corners;

/// Largest finite half-float value: every output format, and Bevy's `Rgba16Float` images,
/// clamp texels to it.
pub const HALF_MAX: f32 = 65504.0;

/// The four texels and weights of a bilinear sample at `uv` of a `width` × `height` image
/// (texel centres at (i + ½)/W, Bevy's and the GPU's convention), clamped at the edges:
/// ((x, y), weight) in the order top-left, top-right, bottom-left, bottom-right.
pub fn bilinear_taps(width: u32, height: u32, u: f32, v: f32) -> [((u32, u32), f32); 4] {
    let corners = bilinear_corners(Vec2::new(u * width as f32, v * height as f32));
    corners.map(|(x, y, w)| {
        let clamp = |i: i64, n: u32| i.clamp(0, i64::from(n) - 1) as u32;
        ((clamp(x, width), clamp(y, height)), w)
    })
}

/// One atlas page of lightmap texels.
#[derive(Clone, Debug, PartialEq)]
pub struct LightmapPage {
    /// Texels across.
    pub width: u32,
    /// Texels down.
    pub height: u32,
    /// E/π per texel, row-major from the top, linear RGB.
    pub texels: Vec<Vec3>,
    /// Texels that belong to a surface (before dilation).
    pub covered: Vec<bool>,
}

impl LightmapPage {
    /// A black page.
    pub fn black(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            texels: vec![Vec3::ZERO; (width * height) as usize],
            covered: vec![false; (width * height) as usize],
        }
    }

    /// The texel at (x, y).
    pub fn get(&self, x: u32, y: u32) -> Vec3 {
        self.texels[(y * self.width + x) as usize]
    }

    /// Bilinear sample at page uv ([`bilinear_taps`]): what the GPU shows.
    pub fn sample_bilinear(&self, u: f32, v: f32) -> Vec3 {
        bilinear_taps(self.width, self.height, u, v)
            .iter()
            .map(|&((x, y), w)| self.get(x, y) * w)
            .sum()
    }

    /// Texel channels above [`HALF_MAX`] (clamped in every output).
    pub fn channels_over_half(&self) -> usize {
        self.texels
            .iter()
            .map(|t| t.to_array().iter().filter(|&&c| c > HALF_MAX).count())
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bilinear_matches_texel_centres() {
        let mut p = LightmapPage::black(2, 1);
        p.texels[0] = Vec3::ZERO;
        p.texels[1] = Vec3::ONE;
        assert_eq!(p.sample_bilinear(0.25, 0.5), Vec3::ZERO);
        assert_eq!(p.sample_bilinear(0.75, 0.5), Vec3::ONE);
        assert!((p.sample_bilinear(0.5, 0.5) - Vec3::splat(0.5)).length() < 1e-6);
        // Clamped beyond the edge.
        assert_eq!(p.sample_bilinear(1.0, 0.5), Vec3::ONE);
    }
}
