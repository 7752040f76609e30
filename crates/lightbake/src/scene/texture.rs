//! Decoded 8-bit textures and their sampling.

use glam::{Vec2, Vec4};

use crate::color::srgb8_to_linear;

/// How a texture wraps outside [0, 1].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Wrap {
    /// Tile (glTF default).
    #[default]
    Repeat,
    /// Tile, mirrored every other time.
    MirroredRepeat,
    /// Clamp to the edge texel.
    ClampToEdge,
}

/// An 8-bit RGBA texture, decoded.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    /// Name or URI, for messages.
    pub name: String,
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// RGBA8 texels, row-major from the top.
    pub rgba8: Vec<[u8; 4]>,
    /// Wrap mode along U.
    pub wrap_u: Wrap,
    /// Wrap mode along V.
    pub wrap_v: Wrap,
}

impl Texture {
    /// Bilinear sample at `uv` (glTF convention: (0,0) is the top-left of the image), decoded
    /// from sRGB to linear RGB; alpha stays linear.
    pub fn sample_srgb(&self, uv: Vec2) -> Vec4 {
        let (w, h) = (self.width as i64, self.height as i64);
        if w == 0 || h == 0 {
            return Vec4::ONE;
        }
        let x = uv.x * self.width as f32 - 0.5;
        let y = uv.y * self.height as f32 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let fetch = |xi: i64, yi: i64| -> Vec4 {
            let xi = wrap_index(xi, w, self.wrap_u);
            let yi = wrap_index(yi, h, self.wrap_v);
            let p = self.rgba8[(yi * w + xi) as usize];
            Vec4::new(
                srgb8_to_linear(p[0]),
                srgb8_to_linear(p[1]),
                srgb8_to_linear(p[2]),
                p[3] as f32 / 255.0,
            )
        };
        let (x0, y0) = (x0 as i64, y0 as i64);
        let top = fetch(x0, y0).lerp(fetch(x0 + 1, y0), fx);
        let bottom = fetch(x0, y0 + 1).lerp(fetch(x0 + 1, y0 + 1), fx);
        top.lerp(bottom, fy)
    }

    /// Mean linear colour over the whole image.
    pub fn mean_srgb(&self) -> Vec4 {
        if self.rgba8.is_empty() {
            return Vec4::ONE;
        }
        let mut sum = [0f64; 4];
        for p in &self.rgba8 {
            sum[0] += srgb8_to_linear(p[0]) as f64;
            sum[1] += srgb8_to_linear(p[1]) as f64;
            sum[2] += srgb8_to_linear(p[2]) as f64;
            sum[3] += p[3] as f64 / 255.0;
        }
        let n = self.rgba8.len() as f64;
        Vec4::new(
            (sum[0] / n) as f32,
            (sum[1] / n) as f32,
            (sum[2] / n) as f32,
            (sum[3] / n) as f32,
        )
    }
}

fn wrap_index(i: i64, n: i64, wrap: Wrap) -> i64 {
    match wrap {
        Wrap::Repeat => i.rem_euclid(n),
        Wrap::ClampToEdge => i.clamp(0, n - 1),
        Wrap::MirroredRepeat => {
            let period = 2 * n;
            let m = i.rem_euclid(period);
            if m < n { m } else { period - 1 - m }
        }
    }
}
