//! A glTF's binary data: its buffers and its images, read under the read rule
//! ([`super::resources`]) and within the import's memory budget.
//!
//! Only the buffers that some buffer view in use (by an accessor, its sparse parts, an image
//! or an extension) lies in are read; the others are neither read nor kept. Every image is
//! decoded at most once, however many textures use it, after its header's size has been
//! checked against what is left of the budget; its encoded bytes are kept for the baked
//! glTF, which copies only what was read here.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::resources::{ReadPolicy, UriSource, used_buffer_views};
use crate::error::{BakeError, Result};

/// Bytes the import may still hold (buffers read and images decoded).
#[derive(Clone, Copy, Debug)]
pub struct Budget {
    /// Bytes left.
    pub left: u64,
    /// The whole budget, for messages.
    pub total: u64,
}

impl Budget {
    /// A budget of `total` bytes.
    pub fn new(total: u64) -> Self {
        Self { left: total, total }
    }

    /// Takes `bytes` for `what`, or says why it cannot.
    ///
    /// # Errors
    /// A phrase naming the need and the budget.
    pub fn take(&mut self, bytes: u64, what: &str) -> std::result::Result<(), String> {
        if bytes > self.left {
            return Err(format!(
                "{what} needs {:.0} MiB, more than the {:.0} MiB left of the import's memory budget of {:.0} MiB (--memory-budget)",
                bytes as f64 / 1048576.0,
                self.left as f64 / 1048576.0,
                self.total as f64 / 1048576.0
            ));
        }
        self.left -= bytes;
        Ok(())
    }
}

/// The uses of every buffer: whether some buffer view in use lies in it.
fn used_buffers(json: &serde_json::Value, buffer_count: usize) -> Vec<bool> {
    let mut used = vec![false; buffer_count];
    let views = used_buffer_views(json);
    for (v, in_use) in views.iter().enumerate() {
        if !in_use {
            continue;
        }
        if let Some(b) = json["bufferViews"][v]["buffer"].as_u64()
            && let Some(u) = used.get_mut(b as usize)
        {
            *u = true;
        }
    }
    used
}

/// Reads every buffer in use (an empty one for the others): a `.glb`'s BIN chunk, a data URI
/// or a file under the read rule, each at least as long as the document declares.
///
/// The files read are added to `files`.
///
/// # Errors
/// [`BakeError::MissingBuffer`] naming the buffer and its URI.
pub fn read_buffers(
    path: &Path,
    document: &gltf::Document,
    json: &serde_json::Value,
    mut blob: Option<Vec<u8>>,
    policy: &ReadPolicy,
    budget: &mut Budget,
    files: &mut Vec<PathBuf>,
) -> Result<Vec<Vec<u8>>> {
    let used = used_buffers(json, document.buffers().len());
    let mut out = Vec::with_capacity(used.len());
    for buffer in document.buffers() {
        let (uri, source) = match buffer.source() {
            gltf::buffer::Source::Uri(u) if u.starts_with("data:") => {
                ("<data URI>".to_string(), Some(u))
            }
            gltf::buffer::Source::Uri(u) => (u.to_string(), Some(u)),
            gltf::buffer::Source::Bin => ("<GLB BIN chunk>".to_string(), None),
        };
        let fail = |message: String| BakeError::MissingBuffer {
            path: path.to_path_buf(),
            index: buffer.index(),
            uri: uri.clone(),
            message,
        };
        if !used[buffer.index()] {
            // Never read; a URI that breaks the rule is refused all the same.
            if let Some(u) = source {
                check_syntax(policy, u).map_err(fail)?;
            }
            out.push(Vec::new());
            continue;
        }
        let declared = buffer.length() as u64;
        budget
            .take(declared, &format!("buffer {}", buffer.index()))
            .map_err(fail)?;
        let data = match source {
            Some(u) => {
                let (source, bytes) = policy.read_prefix(u, declared).map_err(fail)?;
                if let UriSource::File(f) = source {
                    files.push(f);
                }
                bytes
            }
            None => blob
                .take()
                .ok_or_else(|| fail("the file has no BIN chunk".into()))?,
        };
        if (data.len() as u64) < declared {
            return Err(fail(format!(
                "holds {} bytes but the document declares {declared}",
                data.len()
            )));
        }
        out.push(data);
    }
    Ok(out)
}

/// Refuses a URI that breaks the rule in its form alone (a scheme, an absolute path, a bad
/// escape), without looking for the file.
fn check_syntax(policy: &ReadPolicy, uri: &str) -> std::result::Result<(), String> {
    match policy.locate(uri) {
        Err(e) if e.starts_with("cannot be found") => Ok(()),
        Err(e) => Err(e),
        Ok(_) => Ok(()),
    }
}

/// An image decoded to RGBA8.
#[derive(Debug)]
pub struct Decoded {
    /// Width, texels.
    pub width: u32,
    /// Height, texels.
    pub height: u32,
    /// Texels, row-major from the top.
    pub rgba8: Vec<[u8; 4]>,
}

/// Why an image could not be used: refused (the import stops) or unreadable (the material
/// falls back to its factors, with a warning).
pub enum ImageError {
    /// The URI breaks the read rule, or the bytes lie outside their buffer.
    Refused(String),
    /// Missing, undecodable or unsupported.
    Unusable(String),
}

/// Every image of a document, read and decoded on first use.
pub struct Images<'a> {
    document: &'a gltf::Document,
    buffers: &'a [Vec<u8>],
    policy: &'a ReadPolicy,
    decoded: HashMap<usize, Arc<Decoded>>,
    /// The encoded bytes of every image read from a file (for the baked glTF).
    pub files: Vec<Option<Vec<u8>>>,
    /// The image files read (canonical).
    pub paths: Vec<PathBuf>,
}

impl<'a> Images<'a> {
    /// The images of `document` over its `buffers`.
    pub fn new(
        document: &'a gltf::Document,
        buffers: &'a [Vec<u8>],
        policy: &'a ReadPolicy,
    ) -> Self {
        Self {
            document,
            buffers,
            policy,
            decoded: HashMap::new(),
            files: vec![None; document.images().len()],
            paths: Vec::new(),
        }
    }

    /// Image `index` decoded (once), its encoded and decoded bytes taken from `budget`.
    ///
    /// # Errors
    /// [`ImageError`].
    pub fn decode(
        &mut self,
        index: usize,
        budget: &mut Budget,
    ) -> std::result::Result<Arc<Decoded>, ImageError> {
        if let Some(d) = self.decoded.get(&index) {
            return Ok(d.clone());
        }
        let image = self
            .document
            .images()
            .nth(index)
            .ok_or_else(|| ImageError::Refused(format!("image {index} does not exist")))?;
        let (bytes, mime) = match image.source() {
            gltf::image::Source::View { view, mime_type } => {
                let data = self.buffers.get(view.buffer().index()).ok_or_else(|| {
                    ImageError::Refused(format!(
                        "its buffer {} is not loaded",
                        view.buffer().index()
                    ))
                })?;
                let range = view
                    .offset()
                    .checked_add(view.length())
                    .and_then(|end| data.get(view.offset()..end))
                    .ok_or_else(|| {
                        ImageError::Refused(format!(
                            "bufferView {} (bytes {}..+{}) lies beyond its buffer of {} bytes",
                            view.index(),
                            view.offset(),
                            view.length(),
                            data.len()
                        ))
                    })?;
                (range.to_vec(), Some(mime_type))
            }
            gltf::image::Source::Uri { uri, mime_type } => {
                let left = budget.left;
                let (source, bytes) = self.policy.read(uri, left).map_err(|e| {
                    if e.starts_with("cannot be found") || e.starts_with("cannot be opened") {
                        ImageError::Unusable(e)
                    } else {
                        ImageError::Refused(e)
                    }
                })?;
                budget
                    .take(bytes.len() as u64, &format!("image {index}'s file"))
                    .map_err(ImageError::Refused)?;
                if let UriSource::File(f) = source {
                    self.files[index] = Some(bytes.clone());
                    self.paths.push(f);
                }
                (bytes, mime_type)
            }
        };
        let decoded = Arc::new(decode_rgba8(&bytes, mime, budget)?);
        self.decoded.insert(index, decoded.clone());
        Ok(decoded)
    }
}

/// Decodes PNG or JPEG bytes to RGBA8 (16-bit channels keep their high byte), after checking
/// the header's size against the budget.
fn decode_rgba8(
    bytes: &[u8],
    mime: Option<&str>,
    budget: &mut Budget,
) -> std::result::Result<Decoded, ImageError> {
    use image::{DynamicImage, ImageFormat, ImageReader};
    let unusable = |e: String| ImageError::Unusable(e);
    let open = || -> std::result::Result<ImageReader<std::io::Cursor<&[u8]>>, ImageError> {
        let mut reader = ImageReader::new(std::io::Cursor::new(bytes));
        match mime {
            Some("image/png") => reader.set_format(ImageFormat::Png),
            Some("image/jpeg") => reader.set_format(ImageFormat::Jpeg),
            _ => {
                reader = reader
                    .with_guessed_format()
                    .map_err(|e| unusable(e.to_string()))?
            }
        }
        Ok(reader)
    };
    let (w, h) = open()?
        .into_dimensions()
        .map_err(|e| unusable(format!("its header cannot be read ({e})")))?;
    // The decoder's own buffer (up to 8 bytes a texel for 16-bit RGBA) and the RGBA8 copy.
    let texels = w as u64 * h as u64;
    let need = texels.saturating_mul(12);
    let mut reader = open()?;
    budget
        .take(need, &format!("decoding a {w}×{h} image"))
        .map_err(ImageError::Refused)?;
    let mut limits = image::Limits::default();
    limits.max_alloc = Some(need);
    reader.limits(limits);
    let img = reader
        .decode()
        .map_err(|e| unusable(format!("it cannot be decoded ({e})")))?;
    let p = img.as_bytes();
    let rgba8: Vec<[u8; 4]> = match &img {
        DynamicImage::ImageLuma8(_) => p.iter().map(|&r| [r, r, r, 255]).collect(),
        DynamicImage::ImageLumaA8(_) => p
            .chunks_exact(2)
            .map(|c| [c[0], c[0], c[0], c[1]])
            .collect(),
        DynamicImage::ImageRgb8(_) => p.chunks_exact(3).map(|c| [c[0], c[1], c[2], 255]).collect(),
        DynamicImage::ImageRgba8(_) => p
            .chunks_exact(4)
            .map(|c| [c[0], c[1], c[2], c[3]])
            .collect(),
        DynamicImage::ImageLuma16(_) => {
            p.chunks_exact(2).map(|c| [c[1], c[1], c[1], 255]).collect()
        }
        DynamicImage::ImageLumaA16(_) => p
            .chunks_exact(4)
            .map(|c| [c[1], c[1], c[1], c[3]])
            .collect(),
        DynamicImage::ImageRgb16(_) => p.chunks_exact(6).map(|c| [c[1], c[3], c[5], 255]).collect(),
        DynamicImage::ImageRgba16(_) => p
            .chunks_exact(8)
            .map(|c| [c[1], c[3], c[5], c[7]])
            .collect(),
        other => {
            return Err(unusable(format!(
                "its pixel format {:?} is not supported",
                other.color()
            )));
        }
    };
    // The decoder's buffer is freed here; the RGBA8 copy stays.
    budget.left += need - texels.saturating_mul(4);
    if rgba8.len() as u64 != texels {
        return Err(unusable("its texel count does not match its size".into()));
    }
    Ok(Decoded {
        width: w,
        height: h,
        rgba8,
    })
}
