//! Reading glTF accessors into dense arrays, with every bound and type checked (the `gltf`
//! crate's readers reinterpret bytes as whatever type is asked for, and give `None` without a
//! reason when a range is out of bounds).

use gltf::accessor::{DataType, Dimensions};

use crate::error::{BakeError, Result};

/// An accessor's elements copied out tightly packed (sparse substitutions applied).
#[derive(Clone, Debug)]
pub struct Dense {
    /// `count × element_size` bytes, little endian.
    pub bytes: Vec<u8>,
    /// Bytes per element.
    pub element_size: usize,
    /// Component type.
    pub data_type: DataType,
    /// Integer components map to [0, 1] / [−1, 1].
    pub normalized: bool,
}

/// Largest accessor without a bufferView (all zeros but for its sparse values), bytes: 1 GiB.
pub const MAX_ZERO_FILLED_BYTES: usize = 1 << 30;

fn bad(context: &str, message: impl Into<String>) -> BakeError {
    BakeError::BadAccessor {
        context: context.to_string(),
        message: message.into(),
    }
}

/// Bytes `[start, start + len)` of buffer view `view`, checked against the view and the buffer.
fn view_range<'b, B: std::ops::Deref<Target = [u8]>>(
    view: &gltf::buffer::View<'_>,
    buffers: &'b [B],
    start: usize,
    len: usize,
    context: &str,
) -> Result<&'b [u8]> {
    let end = start
        .checked_add(len)
        .ok_or_else(|| bad(context, "byte range overflows"))?;
    if end > view.length() {
        return Err(bad(
            context,
            format!(
                "needs bytes {start}..{end} of bufferView {} but the view is {} bytes long",
                view.index(),
                view.length()
            ),
        ));
    }
    let data = buffers.get(view.buffer().index()).ok_or_else(|| {
        bad(
            context,
            format!("buffer {} is not loaded", view.buffer().index()),
        )
    })?;
    let overflow = || bad(context, "byte range overflows");
    let abs_start = view.offset().checked_add(start).ok_or_else(overflow)?;
    let abs_end = view.offset().checked_add(end).ok_or_else(overflow)?;
    data.get(abs_start..abs_end).ok_or_else(|| {
        bad(
            context,
            format!(
                "bufferView {} reaches byte {abs_end} of buffer {}, which holds {} bytes",
                view.index(),
                view.buffer().index(),
                data.len()
            ),
        )
    })
}

/// Copies an accessor's elements out densely, checking offsets, strides and sparse indices.
///
/// # Errors
/// [`BakeError::BadAccessor`] naming `context` and the problem.
pub fn read_dense<B: std::ops::Deref<Target = [u8]>>(
    accessor: &gltf::Accessor<'_>,
    buffers: &[B],
    context: &str,
) -> Result<Dense> {
    let context = format!("{context} (accessor {})", accessor.index());
    let context = context.as_str();
    let component = accessor.data_type().size();
    let dims = accessor.dimensions();
    if matches!(dims, Dimensions::Mat2 | Dimensions::Mat3) && component < 4 {
        return Err(bad(
            context,
            "padded 8/16-bit matrix accessors are not supported",
        ));
    }
    let element_size = component * dims.multiplicity();
    let count = accessor.count();
    let total = count
        .checked_mul(element_size)
        .ok_or_else(|| bad(context, format!("{count} elements overflow")))?;
    // Every count is checked against the bytes that back it before anything is allocated.
    let source = match accessor.view() {
        Some(view) => {
            let stride = view.stride().unwrap_or(element_size);
            if stride < element_size {
                return Err(bad(
                    context,
                    format!("byteStride {stride} is smaller than the element size {element_size}"),
                ));
            }
            let span = match count {
                0 => 0,
                _ => stride
                    .checked_mul(count - 1)
                    .and_then(|s| s.checked_add(element_size))
                    .ok_or_else(|| bad(context, format!("{count} elements overflow")))?,
            };
            Some((
                view_range(&view, buffers, accessor.offset(), span, context)?,
                stride,
            ))
        }
        None if total > MAX_ZERO_FILLED_BYTES => {
            return Err(bad(
                context,
                format!(
                    "{count} elements without a bufferView would be {total} bytes of zeros, more than the {MAX_ZERO_FILLED_BYTES} allowed"
                ),
            ));
        }
        None => None,
    };
    let sparse_parts = match accessor.sparse() {
        Some(sparse) => {
            let n = sparse.count();
            if n > count {
                return Err(bad(
                    context,
                    format!("sparse count {n} exceeds the accessor's count {count}"),
                ));
            }
            let idx = sparse.indices();
            let index_size = match idx.index_type() {
                gltf::accessor::sparse::IndexType::U8 => 1,
                gltf::accessor::sparse::IndexType::U16 => 2,
                gltf::accessor::sparse::IndexType::U32 => 4,
            };
            let overflow = || bad(context, format!("sparse count {n} overflows"));
            let index_bytes = view_range(
                &idx.view(),
                buffers,
                idx.offset(),
                n.checked_mul(index_size).ok_or_else(overflow)?,
                &format!("{context} sparse indices"),
            )?;
            let vals = sparse.values();
            let value_bytes = view_range(
                &vals.view(),
                buffers,
                vals.offset(),
                n.checked_mul(element_size).ok_or_else(overflow)?,
                &format!("{context} sparse values"),
            )?;
            Some((n, index_size, index_bytes, value_bytes))
        }
        None => None,
    };
    let mut bytes = vec![0u8; total];
    if let Some((src, stride)) = source {
        for (i, dst) in bytes.chunks_exact_mut(element_size).enumerate() {
            dst.copy_from_slice(&src[i * stride..i * stride + element_size]);
        }
    }
    if let Some((n, index_size, index_bytes, value_bytes)) = sparse_parts {
        for k in 0..n {
            let b = &index_bytes[k * index_size..(k + 1) * index_size];
            let target = match index_size {
                1 => b[0] as usize,
                2 => u16::from_le_bytes([b[0], b[1]]) as usize,
                _ => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize,
            };
            if target >= count {
                return Err(bad(
                    context,
                    format!("sparse index {target} is not below the count {count}"),
                ));
            }
            bytes[target * element_size..(target + 1) * element_size]
                .copy_from_slice(&value_bytes[k * element_size..(k + 1) * element_size]);
        }
    }
    Ok(Dense {
        bytes,
        element_size,
        data_type: accessor.data_type(),
        normalized: accessor.normalized(),
    })
}

fn f32_at(b: &[u8], i: usize) -> f32 {
    f32::from_le_bytes([b[4 * i], b[4 * i + 1], b[4 * i + 2], b[4 * i + 3]])
}

/// Reads `VEC3` floats (positions, normals).
///
/// # Errors
/// [`BakeError::BadAccessor`] when the accessor is not `VEC3`/`FLOAT` or out of bounds.
pub fn read_vec3<B: std::ops::Deref<Target = [u8]>>(
    accessor: &gltf::Accessor<'_>,
    buffers: &[B],
    context: &str,
) -> Result<Vec<[f32; 3]>> {
    if accessor.dimensions() != Dimensions::Vec3 || accessor.data_type() != DataType::F32 {
        return Err(bad(
            &format!("{context} (accessor {})", accessor.index()),
            format!(
                "expected VEC3 of FLOAT, found {:?} of {:?}",
                accessor.dimensions(),
                accessor.data_type()
            ),
        ));
    }
    let d = read_dense(accessor, buffers, context)?;
    Ok(d.bytes
        .chunks_exact(12)
        .map(|c| [f32_at(c, 0), f32_at(c, 1), f32_at(c, 2)])
        .collect())
}

/// Reads texture coordinates: `VEC2` of FLOAT, or normalized UNSIGNED_BYTE/UNSIGNED_SHORT.
///
/// # Errors
/// [`BakeError::BadAccessor`] for any other type or out-of-bounds data.
pub fn read_uv<B: std::ops::Deref<Target = [u8]>>(
    accessor: &gltf::Accessor<'_>,
    buffers: &[B],
    context: &str,
) -> Result<Vec<[f32; 2]>> {
    let ctx = format!("{context} (accessor {})", accessor.index());
    if accessor.dimensions() != Dimensions::Vec2 {
        return Err(bad(
            &ctx,
            format!("expected VEC2, found {:?}", accessor.dimensions()),
        ));
    }
    let d = read_dense(accessor, buffers, context)?;
    match (d.data_type, d.normalized) {
        (DataType::F32, _) => Ok(d
            .bytes
            .chunks_exact(8)
            .map(|c| [f32_at(c, 0), f32_at(c, 1)])
            .collect()),
        (DataType::U8, true) => Ok(d
            .bytes
            .chunks_exact(2)
            .map(|c| [c[0] as f32 / 255.0, c[1] as f32 / 255.0])
            .collect()),
        (DataType::U16, true) => Ok(d
            .bytes
            .chunks_exact(4)
            .map(|c| {
                [
                    u16::from_le_bytes([c[0], c[1]]) as f32 / 65535.0,
                    u16::from_le_bytes([c[2], c[3]]) as f32 / 65535.0,
                ]
            })
            .collect()),
        (t, n) => Err(bad(
            &ctx,
            format!("texture coordinates of {t:?} (normalized: {n}) are not allowed"),
        )),
    }
}

/// Reads triangle indices (`SCALAR` of UNSIGNED_BYTE/SHORT/INT).
///
/// # Errors
/// [`BakeError::BadAccessor`] for any other type or out-of-bounds data.
pub fn read_indices<B: std::ops::Deref<Target = [u8]>>(
    accessor: &gltf::Accessor<'_>,
    buffers: &[B],
    context: &str,
) -> Result<Vec<u32>> {
    let ctx = format!("{context} (accessor {})", accessor.index());
    if accessor.dimensions() != Dimensions::Scalar {
        return Err(bad(
            &ctx,
            format!("expected SCALAR, found {:?}", accessor.dimensions()),
        ));
    }
    let d = read_dense(accessor, buffers, context)?;
    match d.data_type {
        DataType::U8 => Ok(d.bytes.iter().map(|&b| b as u32).collect()),
        DataType::U16 => Ok(d
            .bytes
            .chunks_exact(2)
            .map(|c| u16::from_le_bytes([c[0], c[1]]) as u32)
            .collect()),
        DataType::U32 => Ok(d
            .bytes
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect()),
        t => Err(bad(
            &ctx,
            format!("indices must be unsigned integers, found {t:?}"),
        )),
    }
}
