//! BC6H lightmap pages: KTX2, `VK_FORMAT_BC6H_UFLOAT_BLOCK`, one mip level, 16 bytes per 4×4
//! block (1 byte per texel, an eighth of the `Rgba16Float` page), encoded by Intel's ISPC
//! texture compressor through [`ctt`] (the library Bevy 0.20's `CompressedImageSaver` uses).
//!
//! A BC6H block stores one or two colour segments for its 16 texels
//! ([the format](https://learn.microsoft.com/en-us/windows/win32/direct3d11/bc6h-format)).
//! A block that holds texels no surface shows would spend its segments on them: before
//! encoding, each such texel in a block takes the value of the nearest texel the GPU's
//! bilinear filter reads (a covered texel or one beside it), so the block's segments fit only
//! what is seen. [`measure`] decodes the blocks again and compares them with the half-float
//! page over the texels that are read.

use glam::Vec3;

use super::images::to_half;
use crate::lightmap::{HALF_MAX, LightmapPage};

/// Texels per block side.
pub const BLOCK: u32 = 4;

/// What the compression changed, over the texels the bilinear filter reads (covered texels and
/// their eight neighbours), each against its half-float value.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Bc6hError {
    /// √(mean ‖decoded − half‖²) / √(mean ‖half‖²): the RMS error relative to the RMS texel.
    pub rms_relative: f32,
    /// The largest ‖decoded − half‖ / ‖half‖ over texels at least 1% of the RMS texel (darker
    /// ones are measured against 1% of it).
    pub worst_relative: f32,
    /// The 99th percentile of that ratio.
    pub p99_relative: f32,
    /// Texels measured.
    pub texels: usize,
    /// Blocks whose read texels belong to two or more separate islands of read texels: two
    /// charts of one instance, or two parts of one chart around a notch (the layout keeps
    /// instances to their own blocks; this counts what is left).
    pub mixed_blocks: usize,
    /// Blocks holding any read texel.
    pub blocks: usize,
}

impl Bc6hError {
    /// One line for a terminal about page `page`.
    pub fn summary(&self, page: usize) -> String {
        format!(
            "BC6H page {page}: {:.2}% RMS of the RMS texel, 99th percentile {:.1}%, worst {:.1}% over {} texels; {} of {} blocks read two separate islands of texels",
            100.0 * self.rms_relative,
            100.0 * self.p99_relative,
            100.0 * self.worst_relative,
            self.texels,
            self.mixed_blocks,
            self.blocks
        )
    }
}

/// Texels the bilinear filter reads: covered ones and their eight neighbours.
pub fn read_mask(page: &LightmapPage) -> Vec<bool> {
    let (w, h) = (page.width as i64, page.height as i64);
    let mut read = vec![false; page.covered.len()];
    for y in 0..h {
        for x in 0..w {
            if !page.covered[(y * w + x) as usize] {
                continue;
            }
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let (nx, ny) = (x + dx, y + dy);
                    if nx >= 0 && ny >= 0 && nx < w && ny < h {
                        read[(ny * w + nx) as usize] = true;
                    }
                }
            }
        }
    }
    read
}

/// The page as RGBA f32 texels ready for the encoder: clamped to [0, 65504], and each texel
/// that is not read replaced by the nearest read texel of its block (the first in row order
/// among equally near ones).
pub fn block_filled(page: &LightmapPage, read: &[bool]) -> Vec<[f32; 4]> {
    let (w, h) = (page.width, page.height);
    let clamp = |v: Vec3| {
        let c = v.clamp(Vec3::ZERO, Vec3::splat(HALF_MAX));
        [c.x, c.y, c.z, 1.0]
    };
    let mut out: Vec<[f32; 4]> = page.texels.iter().map(|&t| clamp(t)).collect();
    for by in (0..h).step_by(BLOCK as usize) {
        for bx in (0..w).step_by(BLOCK as usize) {
            let cells: Vec<(u32, u32)> = (by..(by + BLOCK).min(h))
                .flat_map(|y| (bx..(bx + BLOCK).min(w)).map(move |x| (x, y)))
                .collect();
            let seen: Vec<(u32, u32)> = cells
                .iter()
                .copied()
                .filter(|&(x, y)| read[(y * w + x) as usize])
                .collect();
            if seen.is_empty() || seen.len() == cells.len() {
                continue;
            }
            for &(x, y) in &cells {
                if read[(y * w + x) as usize] {
                    continue;
                }
                let d2 = |&(sx, sy): &(u32, u32)| {
                    let (dx, dy) = (sx as i32 - x as i32, sy as i32 - y as i32);
                    dx * dx + dy * dy
                };
                let nearest = seen.iter().min_by_key(|s| d2(s)).copied();
                if let Some((sx, sy)) = nearest {
                    out[(y * w + x) as usize] = out[(sy * w + sx) as usize];
                }
            }
        }
    }
    out
}

/// The page as a KTX2 file of BC6H blocks (unsigned half float, no mips, no
/// supercompression), which Bevy loads as `Bc6hRgbUfloat`. Width and height must be multiples
/// of 4, as a GPU needs for a block-compressed texture.
///
/// # Errors
/// A page whose sides are not multiples of 4, or the encoder's message.
pub fn encode_ktx2_bc6h(page: &LightmapPage) -> Result<Vec<u8>, String> {
    if !page.width.is_multiple_of(BLOCK) || !page.height.is_multiple_of(BLOCK) {
        return Err(format!(
            "a BC6H page needs sides that are multiples of 4 texels; this page is {}×{}",
            page.width, page.height
        ));
    }
    let read = read_mask(page);
    let texels = block_filled(page, &read);
    let mut data = Vec::with_capacity(texels.len() * 16);
    for t in &texels {
        for c in t {
            data.extend_from_slice(&c.to_le_bytes());
        }
    }
    let surface = ctt::Surface {
        data,
        width: page.width,
        height: page.height,
        depth: 1,
        stride: page.width * 16,
        slice_stride: 0,
        format: ctt::Format::R32G32B32A32_SFLOAT,
        color_space: ctt::ColorSpace::Linear,
        alpha: ctt::AlphaMode::Opaque,
    };
    let image = ctt::Image {
        surfaces: vec![vec![surface]],
        kind: ctt::TextureKind::Texture2D,
    };
    let settings = ctt::ConvertSettings {
        format: Some(ctt::TargetFormat::Compressed {
            format: ctt::Format::BC6H_UFLOAT_BLOCK,
            encoder: ctt::encoders::Encoder::Auto,
        }),
        container: ctt::Container::ktx2(),
        // ISPC's slower profiles return blocks of texels in the thousands (sunlit ground in
        // lux / π) near 1: 14–28% RMS on seven of the corpus' medium pages, against 0.4–4.4%
        // on all 13 with this one (docs/benchmarks.md).
        quality: ctt::Quality::Basic,
        allow_discarding_alpha: true,
        ..Default::default()
    };
    match ctt::convert(image, settings) {
        Ok(ctt::PipelineOutput::Encoded(bytes)) => Ok(bytes),
        Ok(ctt::PipelineOutput::Raw(_)) => Err("the encoder returned no KTX2 file".into()),
        Err(e) => Err(e.to_string()),
    }
}

/// Decodes a KTX2 file of BC6H blocks (as [`encode_ktx2_bc6h`] writes) to linear RGB.
///
/// # Errors
/// A file that is not one level of unsigned BC6H blocks.
pub fn decode_ktx2_bc6h(bytes: &[u8]) -> Result<(u32, u32, Vec<Vec3>), String> {
    let reader = ktx2::Reader::new(bytes).map_err(|e| e.to_string())?;
    let header = reader.header();
    if header.format != Some(ktx2::Format::BC6H_UFLOAT_BLOCK) {
        return Err(format!("not BC6H (unsigned): {:?}", header.format));
    }
    let (w, h) = (header.pixel_width, header.pixel_height.max(1));
    let level = reader.levels().next().ok_or("no mip level")?;
    let (bw, bh) = (w.div_ceil(BLOCK), h.div_ceil(BLOCK));
    if level.data.len() < (bw * bh * 16) as usize {
        return Err(format!(
            "{} bytes of blocks for a {w}×{h} page",
            level.data.len()
        ));
    }
    let mut out = vec![Vec3::ZERO; (w * h) as usize];
    let mut block = [0.0f32; 48];
    for by in 0..bh {
        for bx in 0..bw {
            let at = ((by * bw + bx) * 16) as usize;
            bcdec_rs::bc6h_float(&level.data[at..at + 16], &mut block, 12, false);
            for j in 0..BLOCK {
                for i in 0..BLOCK {
                    let (x, y) = (bx * BLOCK + i, by * BLOCK + j);
                    if x < w && y < h {
                        let k = (j * 12 + i * 3) as usize;
                        out[(y * w + x) as usize] = Vec3::new(block[k], block[k + 1], block[k + 2]);
                    }
                }
            }
        }
    }
    Ok((w, h, out))
}

/// What a BC6H file changed against the page's half-float values (see [`Bc6hError`]).
///
/// # Errors
/// A file [`decode_ktx2_bc6h`] refuses, or one of another size than the page.
pub fn measure(page: &LightmapPage, bytes: &[u8]) -> Result<Bc6hError, String> {
    let (w, h, decoded) = decode_ktx2_bc6h(bytes)?;
    if (w, h) != (page.width, page.height) {
        return Err(format!(
            "the file is {w}×{h}, the page {}×{}",
            page.width, page.height
        ));
    }
    let read = read_mask(page);
    let half = |v: Vec3| Vec3::from_array(v.to_array().map(|c| to_half(c).to_f32()));
    // (‖decoded − half‖², ‖half‖²) per read texel.
    let squares: Vec<(f32, f32)> = (0..read.len())
        .filter(|&i| read[i])
        .map(|i| {
            let hv = half(page.texels[i]);
            ((decoded[i] - hv).length_squared(), hv.length_squared())
        })
        .collect();
    let n = squares.len();
    if n == 0 {
        return Ok(Bc6hError::default());
    }
    let err2: f64 = squares.iter().map(|&(e, _)| f64::from(e)).sum();
    let ref2: f64 = squares.iter().map(|&(_, r)| f64::from(r)).sum();
    let floor = 0.01 * (ref2 / n as f64).sqrt() as f32;
    let mut ratios: Vec<f32> = squares
        .iter()
        .map(|&(e, r)| e.sqrt() / r.sqrt().max(floor).max(f32::MIN_POSITIVE))
        .collect();
    ratios.sort_by(f32::total_cmp);
    let (blocks, mixed_blocks) = block_islands(page, &read);
    Ok(Bc6hError {
        rms_relative: if ref2 > 0.0 {
            (err2 / ref2).sqrt() as f32
        } else {
            0.0
        },
        worst_relative: ratios.last().copied().unwrap_or(0.0),
        p99_relative: ratios[(ratios.len() - 1) * 99 / 100],
        texels: n,
        mixed_blocks,
        blocks,
    })
}

/// (blocks holding a read texel, blocks whose read texels belong to two or more islands of
/// read texels, 8-connected over the whole page).
fn block_islands(page: &LightmapPage, read: &[bool]) -> (usize, usize) {
    let (w, h) = (page.width as usize, page.height as usize);
    let mut island = vec![u32::MAX; read.len()];
    let mut next = 0u32;
    let mut stack = Vec::new();
    for start in 0..read.len() {
        if !read[start] || island[start] != u32::MAX {
            continue;
        }
        island[start] = next;
        stack.push(start);
        while let Some(i) = stack.pop() {
            let (x, y) = ((i % w) as i64, (i / w) as i64);
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let (nx, ny) = (x + dx, y + dy);
                    if nx < 0 || ny < 0 || nx >= w as i64 || ny >= h as i64 {
                        continue;
                    }
                    let j = ny as usize * w + nx as usize;
                    if read[j] && island[j] == u32::MAX {
                        island[j] = next;
                        stack.push(j);
                    }
                }
            }
        }
        next += 1;
    }
    let (mut blocks, mut mixed) = (0, 0);
    for by in (0..h).step_by(BLOCK as usize) {
        for bx in (0..w).step_by(BLOCK as usize) {
            let mut first = None;
            let mut two = false;
            for y in by..(by + BLOCK as usize).min(h) {
                for x in bx..(bx + BLOCK as usize).min(w) {
                    let id = island[y * w + x];
                    if id == u32::MAX {
                        continue;
                    }
                    match first {
                        None => first = Some(id),
                        Some(f) if f != id => two = true,
                        _ => {}
                    }
                }
            }
            if first.is_some() {
                blocks += 1;
            }
            if two {
                mixed += 1;
            }
        }
    }
    (blocks, mixed)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 16×8 page: a smooth covered gradient on the left, black and uncovered on the right.
    fn page() -> LightmapPage {
        let mut p = LightmapPage::black(16, 8);
        for y in 0..8 {
            for x in 0..7 {
                let i = (y * 16 + x) as usize;
                p.texels[i] = Vec3::new(0.5 + 0.1 * x as f32, 2.0 + 0.05 * y as f32, 40.0);
                p.covered[i] = true;
            }
        }
        p
    }

    #[test]
    fn a_smooth_page_survives_bc6h_within_a_percent() {
        let p = page();
        let bytes = encode_ktx2_bc6h(&p).unwrap();
        // 8 blocks of 16 bytes after the KTX2 header.
        let (w, h, _) = decode_ktx2_bc6h(&bytes).unwrap();
        assert_eq!((w, h), (16, 8));
        let e = measure(&p, &bytes).unwrap();
        assert_eq!(e.texels, 8 * 8, "7 covered columns and the one beside them");
        assert!(e.rms_relative < 0.01, "{e:?}");
        assert!(e.worst_relative < 0.03, "{e:?}");
        assert_eq!((e.blocks, e.mixed_blocks), (4, 0));
    }

    #[test]
    fn texels_nobody_reads_take_their_blocks_nearest_read_value() {
        let p = page();
        let read = read_mask(&p);
        let filled = block_filled(&p, &read);
        // Column 7 is read (beside column 6) and its block is read throughout: unchanged.
        assert_eq!(filled[7], [0.0, 0.0, 0.0, 1.0]);
        // Columns 8..16 are in blocks with no read texel: unchanged.
        assert_eq!(filled[8], [0.0, 0.0, 0.0, 1.0]);
        // Block (4..8) has every texel read: unchanged.
        assert_eq!(filled[4][0], p.texels[4].x);
        // A page whose covered texels stop mid-block: the unread texels copy a read one.
        let mut q = LightmapPage::black(4, 4);
        q.texels[0] = Vec3::splat(3.0);
        q.covered[0] = true;
        let read = read_mask(&q);
        let filled = block_filled(&q, &read);
        assert_eq!(filled[15], [0.0, 0.0, 0.0, 1.0], "(1,1) is read and black");
        assert_eq!(
            filled[3], filled[1],
            "(3,0) copies (1,0), its nearest read texel"
        );
        assert_eq!(filled[2], filled[1]);
    }

    #[test]
    fn a_page_that_is_not_whole_blocks_is_refused() {
        let p = LightmapPage::black(6, 8);
        let e = encode_ktx2_bc6h(&p).unwrap_err();
        assert!(e.contains("multiples of 4") && e.contains("6×8"), "{e}");
    }

    #[test]
    fn two_charts_in_one_block_are_counted() {
        let mut p = LightmapPage::black(8, 4);
        for (x, v) in [(0u32, 1.0f32), (4, 9.0)] {
            p.texels[x as usize] = Vec3::splat(v);
            p.covered[x as usize] = true;
        }
        let read = read_mask(&p);
        // Reads reach x = 0..=1 and x = 3..=5: two islands (x = 2 is not read), and the
        // first block holds texels of both.
        assert_eq!(block_islands(&p, &read), (2, 1));
    }
}
