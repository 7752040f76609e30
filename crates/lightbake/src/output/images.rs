//! Lightmap image encoders: OpenEXR (RGB half float), Radiance `.hdr` (RGBE), KTX2
//! (`VK_FORMAT_R16G16B16A16_SFLOAT`, which Bevy loads as `Rgba16Float`) and a tonemapped
//! sRGB PNG preview.
//!
//! Half floats top out at 65504: larger values are clamped (and reported by the caller),
//! never written as infinity. NaN never reaches here (the bake checks its results).

use half::f16;

use crate::lightmap::{HALF_MAX, LightmapPage};

/// Converts to half, clamping to [0, 65504].
pub(crate) fn to_half(v: f32) -> f16 {
    f16::from_f32(v.clamp(0.0, HALF_MAX))
}

/// OpenEXR, RGB channels of 16-bit floats, ZIP compressed, scan lines top to bottom.
///
/// # Errors
/// The encoder's message.
pub fn encode_exr(page: &LightmapPage) -> Result<Vec<u8>, String> {
    use exr::prelude::*;
    let (w, h) = (page.width as usize, page.height as usize);
    let channels = SpecificChannels::rgb(|pos: Vec2<usize>| {
        let t = page.texels[pos.y() * w + pos.x()];
        (to_half(t.x), to_half(t.y), to_half(t.z))
    });
    let image = Image::from_encoded_channels((w, h), Encoding::SMALL_LOSSLESS, channels);
    let mut bytes = std::io::Cursor::new(Vec::new());
    image
        .write()
        .non_parallel()
        .to_buffered(&mut bytes)
        .map_err(|e| e.to_string())?;
    Ok(bytes.into_inner())
}

/// Radiance RGBE (`.hdr`).
///
/// # Errors
/// The encoder's message.
pub fn encode_hdr(page: &LightmapPage) -> Result<Vec<u8>, String> {
    let pixels: Vec<image::Rgb<f32>> = page
        .texels
        .iter()
        .map(|t| image::Rgb([t.x.max(0.0), t.y.max(0.0), t.z.max(0.0)]))
        .collect();
    let mut out = Vec::new();
    image::codecs::hdr::HdrEncoder::new(&mut out)
        .encode(&pixels, page.width as usize, page.height as usize)
        .map_err(|e| e.to_string())?;
    Ok(out)
}

/// KTX2 container, one mip level, `VK_FORMAT_R16G16B16A16_SFLOAT` (alpha 1), linear
/// BT.709 data format descriptor, no supercompression.
pub fn encode_ktx2(page: &LightmapPage) -> Vec<u8> {
    encode_ktx2_texels([page.width, page.height, 0], &page.texels)
}

/// [`encode_ktx2`] of any texels: `size` is (width, height, depth), depth 0 for a 2D
/// texture and at least 1 for a 3D one (`pixelDepth`; Bevy loads depth > 1 as a 3D
/// texture), texels x fastest, then y, then z.
///
/// # Panics
/// When `texels` does not hold width × height × max(depth, 1) texels.
pub fn encode_ktx2_texels(size: [u32; 3], texels: &[glam::Vec3]) -> Vec<u8> {
    assert_eq!(
        texels.len(),
        (size[0] * size[1] * size[2].max(1)) as usize,
        "texel count against the KTX2 size"
    );
    const VK_FORMAT_R16G16B16A16_SFLOAT: u32 = 97;
    const IDENTIFIER: [u8; 12] = [
        0xAB, b'K', b'T', b'X', b' ', b'2', b'0', 0xBB, b'\r', b'\n', 0x1A, b'\n',
    ];
    let put32 = |v: &mut Vec<u8>, x: u32| v.extend_from_slice(&x.to_le_bytes());
    let put64 = |v: &mut Vec<u8>, x: u64| v.extend_from_slice(&x.to_le_bytes());

    // Data format descriptor: one basic block with four 16-bit float samples.
    let mut dfd = Vec::new();
    let block_size = 24 + 16 * 4;
    put32(&mut dfd, 4 + block_size); // dfdTotalSize
    put32(&mut dfd, 0); // vendorId 0 (Khronos), descriptorType 0 (basic)
    dfd.extend_from_slice(&2u16.to_le_bytes()); // versionNumber (KDF 1.3)
    dfd.extend_from_slice(&(block_size as u16).to_le_bytes());
    dfd.extend_from_slice(&[1, 1, 1, 0]); // model RGBSDA, primaries BT709, transfer LINEAR, flags
    dfd.extend_from_slice(&[0, 0, 0, 0]); // texelBlockDimension (1×1×1×1, stored minus one)
    dfd.extend_from_slice(&[8, 0, 0, 0, 0, 0, 0, 0]); // bytesPlane
    for (i, channel) in [0u8, 1, 2, 15].into_iter().enumerate() {
        dfd.extend_from_slice(&((16 * i) as u16).to_le_bytes()); // bitOffset
        dfd.push(15); // bitLength − 1
        dfd.push(0xC0 | channel); // FLOAT | SIGNED | channel id
        dfd.extend_from_slice(&[0, 0, 0, 0]); // samplePosition
        put32(&mut dfd, 0xBF80_0000); // sampleLower = −1.0
        put32(&mut dfd, 0x3F80_0000); // sampleUpper = 1.0
    }
    // Key/value data: the writer.
    let mut kvd = Vec::new();
    let kv = b"KTXwriter\0lightbake\0";
    put32(&mut kvd, kv.len() as u32);
    kvd.extend_from_slice(kv);
    while kvd.len() % 4 != 0 {
        kvd.push(0);
    }
    // Texel data.
    let mut data = Vec::with_capacity(texels.len() * 8);
    for t in texels {
        for c in [to_half(t.x), to_half(t.y), to_half(t.z), f16::ONE] {
            data.extend_from_slice(&c.to_le_bytes());
        }
    }

    let header_len = 12 + 9 * 4 + 4 * 4 + 2 * 8 + 3 * 8; // identifier, header, index, one level
    let dfd_offset = header_len;
    let kvd_offset = dfd_offset + dfd.len();
    let mut data_offset = kvd_offset + kvd.len();
    data_offset = data_offset.div_ceil(8) * 8; // align to lcm(texel block size 8, 4)

    let mut out = Vec::with_capacity(data_offset + data.len());
    out.extend_from_slice(&IDENTIFIER);
    put32(&mut out, VK_FORMAT_R16G16B16A16_SFLOAT);
    put32(&mut out, 2); // typeSize
    put32(&mut out, size[0]);
    put32(&mut out, size[1]);
    put32(&mut out, size[2]); // pixelDepth
    put32(&mut out, 0); // layerCount
    put32(&mut out, 1); // faceCount
    put32(&mut out, 1); // levelCount
    put32(&mut out, 0); // supercompressionScheme
    put32(&mut out, dfd_offset as u32);
    put32(&mut out, dfd.len() as u32);
    put32(&mut out, kvd_offset as u32);
    put32(&mut out, kvd.len() as u32);
    put64(&mut out, 0); // sgdByteOffset
    put64(&mut out, 0); // sgdByteLength
    put64(&mut out, data_offset as u64);
    put64(&mut out, data.len() as u64);
    put64(&mut out, data.len() as u64);
    debug_assert_eq!(out.len(), header_len);
    out.extend_from_slice(&dfd);
    out.extend_from_slice(&kvd);
    out.resize(data_offset, 0);
    out.extend_from_slice(&data);
    out
}

/// A tonemapped sRGB PNG to look at: exposure puts the 99th percentile of the covered texels'
/// luminance at 95% white through the curve 1 − e^(−x), then the sRGB transfer function.
///
/// # Errors
/// The encoder's message.
pub fn encode_preview_png(page: &LightmapPage) -> Result<Vec<u8>, String> {
    let lum = crate::color::luminance;
    let mut covered: Vec<f32> = page
        .texels
        .iter()
        .zip(&page.covered)
        .filter(|(_, c)| **c)
        .map(|(t, _)| lum(*t))
        .collect();
    covered.sort_by(f32::total_cmp);
    let p99 = covered
        .get(((covered.len() as f32 * 0.99) as usize).min(covered.len().saturating_sub(1)))
        .copied()
        .unwrap_or(0.0);
    // 1 − e^(−3) ≈ 0.95
    let exposure = if p99 > 0.0 { 3.0 / p99 } else { 1.0 };
    let encode = |x: f32| -> u8 {
        let t = (1.0 - (-x.max(0.0)).exp()).clamp(0.0, 1.0);
        let s = if t <= 0.003_130_8 {
            12.92 * t
        } else {
            1.055 * t.powf(1.0 / 2.4) - 0.055
        };
        (s * 255.0 + 0.5) as u8
    };
    let mut rgb = Vec::with_capacity(page.texels.len() * 3);
    for t in &page.texels {
        let c = *t * exposure;
        rgb.extend_from_slice(&[encode(c.x), encode(c.y), encode(c.z)]);
    }
    let mut out = Vec::new();
    let img =
        image::RgbImage::from_raw(page.width, page.height, rgb).ok_or("image size mismatch")?;
    img.write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png)
        .map_err(|e| e.to_string())?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn page() -> LightmapPage {
        let mut p = LightmapPage::black(5, 3);
        for (i, t) in p.texels.iter_mut().enumerate() {
            *t = Vec3::new(i as f32 * 0.5, 1.0, 100_000.0 * (i % 2) as f32);
        }
        p.covered.iter_mut().for_each(|c| *c = true);
        p
    }

    #[test]
    fn exr_round_trips_through_the_image_crate() {
        let p = page();
        let bytes = encode_exr(&p).unwrap();
        let img = image::load_from_memory_with_format(&bytes, image::ImageFormat::OpenExr)
            .unwrap()
            .to_rgba32f();
        assert_eq!((img.width(), img.height()), (5, 3));
        for (i, px) in img.pixels().enumerate() {
            let t = p.texels[i];
            assert!((px[0] - t.x).abs() <= t.x * 1e-3 + 1e-6);
            assert_eq!(px[1], 1.0);
            assert!(px[2].is_finite() && px[2] <= HALF_MAX);
        }
        assert_eq!(p.channels_over_half(), 7);
    }

    #[test]
    fn ktx2_is_read_back_by_the_ktx2_crate() {
        let p = page();
        let bytes = encode_ktx2(&p);
        let reader = ktx2::Reader::new(&bytes[..]).unwrap();
        let header = reader.header();
        assert_eq!(header.format, Some(ktx2::Format::R16G16B16A16_SFLOAT));
        assert_eq!(
            (header.pixel_width, header.pixel_height, header.level_count),
            (5, 3, 1)
        );
        let level = reader.levels().next().unwrap();
        assert_eq!(level.data.len(), 5 * 3 * 8);
        let texel = |i: usize, c: usize| {
            f16::from_le_bytes([level.data[i * 8 + 2 * c], level.data[i * 8 + 2 * c + 1]]).to_f32()
        };
        assert_eq!(texel(4, 0), 2.0);
        assert_eq!(texel(4, 3), 1.0);
        let Some(ktx2::dfd::Block::Basic(basic)) = reader.dfd_blocks().first() else {
            panic!("no basic data format descriptor: {:?}", reader.dfd_blocks());
        };
        assert_eq!(basic.bytes_planes[0], 8);
        assert_eq!(basic.sample_information.len(), 4);
    }

    #[test]
    fn hdr_and_png_decode() {
        let p = page();
        let hdr =
            image::load_from_memory_with_format(&encode_hdr(&p).unwrap(), image::ImageFormat::Hdr)
                .unwrap();
        assert_eq!((hdr.width(), hdr.height()), (5, 3));
        let png = image::load_from_memory_with_format(
            &encode_preview_png(&p).unwrap(),
            image::ImageFormat::Png,
        )
        .unwrap();
        assert_eq!((png.width(), png.height()), (5, 3));
    }
}
