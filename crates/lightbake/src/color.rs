//! Colour arithmetic shared by every stage: the luminance of linear Rec. 709 RGB and the sRGB
//! transfer function (IEC 61966-2-1).

use glam::Vec3;

/// Luminance weights of linear Rec. 709 RGB (the Y row of the RGB → XYZ matrix).
pub const LUMINANCE_WEIGHTS: Vec3 = Vec3::new(0.2126, 0.7152, 0.0722);

/// Luminance of a linear Rec. 709 RGB colour (same unit as the colour).
#[inline]
pub fn luminance(c: Vec3) -> f32 {
    c.dot(LUMINANCE_WEIGHTS)
}

/// Decodes one sRGB-encoded channel in [0, 1] to linear.
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Decodes one 8-bit sRGB channel to linear, via a 256-entry table.
pub fn srgb8_to_linear(v: u8) -> f32 {
    static TABLE: std::sync::OnceLock<[f32; 256]> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| std::array::from_fn(|i| srgb_to_linear(i as f32 / 255.0)))[v as usize]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_known_values() {
        assert_eq!(srgb8_to_linear(0), 0.0);
        assert_eq!(srgb8_to_linear(255), 1.0);
        // sRGB 128/255 = 0.50196 decodes to ((0.50196 + 0.055)/1.055)^2.4 = 0.215861.
        assert!((srgb8_to_linear(128) - 0.215_861).abs() < 1e-5);
        assert_eq!(srgb_to_linear(0.04), 0.04 / 12.92, "the linear segment");
        assert!((luminance(Vec3::ONE) - 1.0).abs() < 1e-6);
    }
}
