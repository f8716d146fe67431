//! glTF accessors read by hand, with every count, offset and index checked: dense data through its buffer view
//! (byte stride respected), sparse accessors (glTF 2.0 §3.6.2.3: the base view, or zeros without one, with the
//! sparse indices' elements replaced by the sparse values), and normalized integer components decoded as
//! glTF 2.0 §3.11 and `KHR_mesh_quantization` define them (signed: `max(c / (2^(b-1) - 1), -1)`, unsigned:
//! `c / (2^b - 1)`). Each use ([`Usage`]) accepts the core component types for its semantic plus the
//! quantized ones of `KHR_mesh_quantization`.
//!
//! Errors ([`AccessorError`]) name the accessor and the problem in one line; the caller adds the file and
//! primitive.
//! Nothing is allocated by a count before the count is checked: a dense accessor's elements must lie inside
//! its view, and the bytes of any accessor must fit the memory budget.

use crate::limits::Limits;
use gltf::accessor::{DataType, Dimensions};

/// What an accessor is read as; each fixes the element type and the component types accepted.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(super) enum Usage {
    /// A primitive's index list (SCALAR u8/u16/u32).
    Indices,
    /// POSITION (VEC3 f32; quantized: i8/u8/i16/u16, normalized or not).
    Position,
    /// NORMAL (VEC3 f32; quantized: i8/i16 normalized).
    Normal,
    /// TANGENT (VEC4 f32; quantized: i8/i16 normalized).
    Tangent,
    /// TEXCOORD_n (VEC2 f32 or u8/u16 normalized; quantized: i8/u8/i16/u16, normalized or not).
    TexCoord,
    /// COLOR_n as RGB (VEC3 f32 or u8/u16 normalized).
    ColorRgb,
    /// COLOR_n as RGBA (VEC4 f32 or u8/u16 normalized).
    ColorRgba,
    /// JOINTS_n (VEC4 u8/u16).
    Joints,
    /// WEIGHTS_n (VEC4 f32 or u8/u16 normalized).
    Weights,
    /// A morph target's POSITION displacement (VEC3 f32; quantized: i8/i16, normalized or not).
    PositionDelta,
    /// A morph target's NORMAL or TANGENT displacement (VEC3 f32; quantized: i8/i16 normalized).
    DirectionDelta,
    /// An animation sampler's key times (SCALAR f32).
    KeyTimes,
    /// Animated translations or scales (VEC3 f32).
    KeyVec3,
    /// Animated rotations (VEC4 f32, or i8/u8/i16/u16 normalized).
    KeyRotation,
    /// Animated morph weights (SCALAR f32, or i8/u8/i16/u16 normalized).
    KeyWeights,
    /// A skin's inverseBindMatrices (MAT4 f32).
    InverseBindMatrices,
    /// An attribute Nimbus does not read: any type, only its bytes checked.
    Unread,
}

/// Whether a component type must, may or must not be normalized.
#[derive(Clone, Copy)]
enum Norm {
    Yes,
    No,
    Either,
}

impl Usage {
    /// The element type and the accepted (component type, normalization) pairs; `None` for `Unread`.
    fn accepts(self) -> Option<(Dimensions, &'static [(DataType, Norm)])> {
        use DataType::{F32, I16, I8, U16, U32, U8};
        use Dimensions::{Mat4, Scalar, Vec2, Vec3, Vec4};
        use Norm::{Either, No, Yes};
        const QUANTIZED_ANY: &[(DataType, Norm)] = &[
            (F32, No),
            (I8, Either),
            (U8, Either),
            (I16, Either),
            (U16, Either),
        ];
        const UNIT_SIGNED: &[(DataType, Norm)] = &[(F32, No), (I8, Yes), (I16, Yes)];
        const KEY_NORMALIZED: &[(DataType, Norm)] =
            &[(F32, No), (I8, Yes), (U8, Yes), (I16, Yes), (U16, Yes)];
        match self {
            Usage::Indices => Some((Scalar, &[(U8, No), (U16, No), (U32, No)])),
            Usage::Position => Some((Vec3, QUANTIZED_ANY)),
            Usage::Normal => Some((Vec3, UNIT_SIGNED)),
            Usage::Tangent => Some((Vec4, UNIT_SIGNED)),
            Usage::TexCoord => Some((Vec2, QUANTIZED_ANY)),
            Usage::ColorRgb => Some((Vec3, &[(F32, No), (U8, Yes), (U16, Yes)])),
            Usage::ColorRgba => Some((Vec4, &[(F32, No), (U8, Yes), (U16, Yes)])),
            Usage::Joints => Some((Vec4, &[(U8, No), (U16, No)])),
            Usage::Weights => Some((Vec4, &[(F32, No), (U8, Yes), (U16, Yes)])),
            Usage::PositionDelta => Some((Vec3, &[(F32, No), (I8, Either), (I16, Either)])),
            Usage::DirectionDelta => Some((Vec3, UNIT_SIGNED)),
            Usage::InverseBindMatrices => Some((Mat4, &[(F32, No)])),
            Usage::KeyTimes => Some((Scalar, &[(F32, No)])),
            Usage::KeyVec3 => Some((Vec3, &[(F32, No)])),
            Usage::KeyRotation => Some((Vec4, KEY_NORMALIZED)),
            Usage::KeyWeights => Some((Scalar, KEY_NORMALIZED)),
            Usage::Unread => None,
        }
    }
}

/// An accessor that cannot be read: `accessor N: ` and the problem.
#[derive(Debug, thiserror::Error)]
#[error("accessor {accessor}: {problem}")]
pub(super) struct AccessorError {
    /// The accessor's index.
    pub(super) accessor: usize,
    /// What is wrong with it.
    pub(super) problem: AccessorProblem,
}

/// What is wrong with an accessor ([`AccessorError`]).
#[derive(Debug, thiserror::Error)]
pub(super) enum AccessorProblem {
    /// Its type or component type is not one its use reads.
    #[error("{found} cannot be read as {usage:?} ({accepted})")]
    WrongType {
        /// Its type and component type, in words.
        found: String,
        /// What it was read as.
        usage: Usage,
        /// The type and component types that use accepts, in words.
        accepted: String,
    },
    /// It has no elements.
    #[error("count is 0")]
    CountZero,
    /// Its view's byte stride is smaller than an element.
    #[error("byteStride {stride} is smaller than the element size {element}")]
    StrideTooSmall {
        /// The byte stride.
        stride: usize,
        /// The element size in bytes.
        element: usize,
    },
    /// Its elements run past the end of its buffer view.
    #[error("{count} elements run past the end of buffer view {view}")]
    PastViewEnd {
        /// Its element count.
        count: usize,
        /// The buffer view's index.
        view: usize,
    },
    /// A buffer view it reads runs past the end of its buffer.
    #[error("buffer view {view} (bytes {offset}+{length}) runs past the end of its buffer ({buffer} bytes)")]
    ViewPastBuffer {
        /// The buffer view's index.
        view: usize,
        /// Its byte offset.
        offset: usize,
        /// Its byte length.
        length: usize,
        /// The buffer's length in bytes.
        buffer: usize,
    },
    /// A sparse accessor's count is 0 or more than the accessor's.
    #[error("sparse.count is {n}; it must be between 1 and the accessor's count {count}")]
    SparseCount {
        /// The sparse count.
        n: usize,
        /// The accessor's count.
        count: usize,
    },
    /// A sparse index is past the accessor's elements.
    #[error("sparse.indices[{k}] is {i}, past the accessor's {count} elements")]
    SparseIndexPastEnd {
        /// Its position among the sparse indices.
        k: usize,
        /// The index.
        i: usize,
        /// The accessor's count.
        count: usize,
    },
    /// The sparse indices do not strictly increase.
    #[error("sparse.indices[{k}] is {i}; the indices must be strictly increasing")]
    SparseIndexNotIncreasing {
        /// Its position among the sparse indices.
        k: usize,
        /// The index.
        i: usize,
    },
    /// The sparse indices or values run past the end of their buffer view.
    #[error("{what}: {n} items of {size} bytes at byteOffset {offset} run past the end of buffer view {view} ({view_bytes} bytes)")]
    SectionPastView {
        /// `sparse.indices` or `sparse.values`.
        what: &'static str,
        /// The number of items.
        n: usize,
        /// An item's size in bytes.
        size: usize,
        /// The byte offset in the view.
        offset: usize,
        /// The buffer view's index.
        view: usize,
        /// The buffer view's length in bytes.
        view_bytes: usize,
    },
    /// Its elements (a sparse accessor without a view) do not fit the memory budget.
    #[error("{0}")]
    OverBudget(crate::limits::OverBudget),
}

/// Reads an accessor as `usage` into `count × components` floats, element after element, normalized integers
/// decoded to [-1, 1] or [0, 1] and other integers converted as they are.
pub(super) fn read_floats(
    accessor: &gltf::Accessor,
    usage: Usage,
    buffers: &[gltf::buffer::Data],
    limits: &Limits,
) -> Result<Vec<f32>, AccessorError> {
    let packed = read_packed(accessor, usage, buffers, limits)?;
    let decode = decoder(accessor.data_type(), accessor.normalized());
    let size = accessor.data_type().size();
    Ok(packed.chunks_exact(size).map(decode).collect())
}

/// Reads an index accessor (SCALAR u8, u16 or u32).
pub(super) fn read_indices(
    accessor: &gltf::Accessor,
    buffers: &[gltf::buffer::Data],
    limits: &Limits,
) -> Result<Vec<u32>, AccessorError> {
    let packed = read_packed(accessor, Usage::Indices, buffers, limits)?;
    let size = accessor.data_type().size();
    Ok(packed.chunks_exact(size).map(unsigned).collect())
}

/// Reads a JOINTS_n accessor (VEC4 u8 or u16) as joint indices.
pub(super) fn read_joints(
    accessor: &gltf::Accessor,
    buffers: &[gltf::buffer::Data],
    limits: &Limits,
) -> Result<Vec<[u32; 4]>, AccessorError> {
    let packed = read_packed(accessor, Usage::Joints, buffers, limits)?;
    let size = accessor.data_type().size();
    let flat: Vec<u32> = packed.chunks_exact(size).map(unsigned).collect();
    Ok(flat
        .chunks_exact(4)
        .map(|c| [c[0], c[1], c[2], c[3]])
        .collect())
}

/// Checks that an accessor's elements (and sparse substitutions) lie inside their buffer views.
pub(super) fn check_bytes(
    accessor: &gltf::Accessor,
    buffers: &[gltf::buffer::Data],
    limits: &Limits,
) -> Result<(), AccessorError> {
    read_packed(accessor, Usage::Unread, buffers, limits).map(drop)
}

/// A little-endian unsigned integer of 1, 2 or 4 bytes.
fn unsigned(bytes: &[u8]) -> u32 {
    bytes
        .iter()
        .rev()
        .fold(0u32, |acc, &b| (acc << 8) | u32::from(b))
}

/// The function decoding one component of `data_type` to a float (glTF 2.0 §3.11 for normalized ones).
fn decoder(data_type: DataType, normalized: bool) -> fn(&[u8]) -> f32 {
    match (data_type, normalized) {
        (DataType::F32, _) => |b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
        (DataType::I8, false) => |b| f32::from(b[0] as i8),
        (DataType::I8, true) => |b| (f32::from(b[0] as i8) / 127.0).max(-1.0),
        (DataType::U8, false) => |b| f32::from(b[0]),
        (DataType::U8, true) => |b| f32::from(b[0]) / 255.0,
        (DataType::I16, false) => |b| f32::from(i16::from_le_bytes([b[0], b[1]])),
        (DataType::I16, true) => {
            |b| (f32::from(i16::from_le_bytes([b[0], b[1]])) / 32767.0).max(-1.0)
        }
        (DataType::U16, false) => |b| f32::from(u16::from_le_bytes([b[0], b[1]])),
        (DataType::U16, true) => |b| f32::from(u16::from_le_bytes([b[0], b[1]])) / 65535.0,
        (DataType::U32, _) => |b| unsigned(b) as f32,
    }
}

/// Checks the accessor against `usage` and returns its elements' bytes packed (no stride), sparse values
/// substituted.
fn read_packed(
    accessor: &gltf::Accessor,
    usage: Usage,
    buffers: &[gltf::buffer::Data],
    limits: &Limits,
) -> Result<Vec<u8>, AccessorError> {
    let index = accessor.index();
    let bad = |problem| AccessorError {
        accessor: index,
        problem,
    };
    let dims = check_usage(accessor, usage).map_err(&bad)?;
    let count = accessor.count();
    if count == 0 {
        return Err(bad(AccessorProblem::CountZero));
    }
    let element = accessor.data_type().size() * dims.multiplicity();
    let mut packed = match accessor.view() {
        Some(view) => dense_elements(accessor, &view, element, buffers).map_err(&bad)?,
        None => {
            // Only a sparse accessor may omit its view (checked by the gltf crate's validation); its base
            // is zeros, and its count is bounded only by the memory budget.
            limits
                .check_items(
                    format_args!("accessor {index} ({count} elements)"),
                    count as u64,
                    element as u64,
                )
                .map_err(|e| bad(AccessorProblem::OverBudget(e)))?;
            vec![0u8; count * element]
        }
    };
    if let Some(sparse) = accessor.sparse() {
        substitute_sparse(&sparse, &mut packed, count, element, buffers).map_err(&bad)?;
    }
    Ok(packed)
}

/// The dimensions `usage` reads the accessor as, if its type and component type are among those `usage`
/// accepts (any, for a usage without a list); else an error listing them.
fn check_usage(accessor: &gltf::Accessor, usage: Usage) -> Result<Dimensions, AccessorProblem> {
    let (data_type, dimensions, normalized) = (
        accessor.data_type(),
        accessor.dimensions(),
        accessor.normalized(),
    );
    let own = [(data_type, Norm::Either)];
    let (dims, types) = usage.accepts().unwrap_or((dimensions, &own[..]));
    let type_ok = types.iter().any(|&(t, n)| {
        t == data_type
            && match n {
                Norm::Yes => normalized,
                Norm::No => !normalized,
                Norm::Either => true,
            }
    });
    if dimensions != dims || !type_ok {
        let norm = if normalized { " normalized" } else { "" };
        return Err(AccessorProblem::WrongType {
            found: format!("type {dimensions:?} with{norm} componentType {data_type:?}"),
            usage,
            accepted: format!(
                "{dims:?} of {}",
                types
                    .iter()
                    .map(|(t, n)| match n {
                        Norm::Yes => format!("{t:?} normalized"),
                        Norm::No => format!("{t:?}"),
                        Norm::Either => format!("{t:?} (normalized or not)"),
                    })
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        });
    }
    Ok(dims)
}

/// The accessor's `element`-byte elements packed out of its buffer `view` (its byte stride respected), each
/// checked to lie inside the view.
fn dense_elements(
    accessor: &gltf::Accessor,
    view: &gltf::buffer::View,
    element: usize,
    buffers: &[gltf::buffer::Data],
) -> Result<Vec<u8>, AccessorProblem> {
    let count = accessor.count();
    let bytes = view_bytes(view, buffers)?;
    let stride = view.stride().unwrap_or(element);
    if stride < element {
        return Err(AccessorProblem::StrideTooSmall { stride, element });
    }
    let end = (count - 1)
        .checked_mul(stride)
        .and_then(|v| v.checked_add(accessor.offset()))
        .and_then(|v| v.checked_add(element));
    if end.is_none_or(|e| e > bytes.len()) {
        return Err(AccessorProblem::PastViewEnd {
            count,
            view: view.index(),
        });
    }
    let mut packed = Vec::with_capacity(count * element);
    for i in 0..count {
        let start = accessor.offset() + i * stride;
        packed.extend_from_slice(&bytes[start..start + element]);
    }
    Ok(packed)
}

/// The bytes of a buffer view, checked to lie inside its buffer.
fn view_bytes<'b>(
    view: &gltf::buffer::View,
    buffers: &'b [gltf::buffer::Data],
) -> Result<&'b [u8], AccessorProblem> {
    let buffer = buffers.get(view.buffer().index()).map_or(&[][..], |b| &b.0);
    view.offset()
        .checked_add(view.length())
        .and_then(|end| buffer.get(view.offset()..end))
        .ok_or(AccessorProblem::ViewPastBuffer {
            view: view.index(),
            offset: view.offset(),
            length: view.length(),
            buffer: buffer.len(),
        })
}

/// Replaces the elements the sparse indices name with the sparse values (glTF 2.0 §3.6.2.3): `count`
/// indices, strictly increasing and below the accessor's count, and as many tightly packed values.
fn substitute_sparse(
    sparse: &gltf::accessor::sparse::Sparse,
    packed: &mut [u8],
    count: usize,
    element: usize,
    buffers: &[gltf::buffer::Data],
) -> Result<(), AccessorProblem> {
    let n = sparse.count();
    if n == 0 || n > count {
        return Err(AccessorProblem::SparseCount { n, count });
    }
    let indices = sparse.indices();
    let index_size = match indices.index_type() {
        gltf::accessor::sparse::IndexType::U8 => 1,
        gltf::accessor::sparse::IndexType::U16 => 2,
        gltf::accessor::sparse::IndexType::U32 => 4,
    };
    let values = sparse.values();
    let index_bytes = section(
        &indices.view(),
        indices.offset(),
        n,
        index_size,
        "sparse.indices",
        buffers,
    )?;
    let value_bytes = section(
        &values.view(),
        values.offset(),
        n,
        element,
        "sparse.values",
        buffers,
    )?;
    let mut previous: Option<usize> = None;
    for (k, (i, value)) in index_bytes
        .chunks_exact(index_size)
        .zip(value_bytes.chunks_exact(element))
        .enumerate()
    {
        let i = unsigned(i) as usize;
        if i >= count {
            return Err(AccessorProblem::SparseIndexPastEnd { k, i, count });
        }
        if previous.is_some_and(|p| i <= p) {
            return Err(AccessorProblem::SparseIndexNotIncreasing { k, i });
        }
        previous = Some(i);
        packed[i * element..(i + 1) * element].copy_from_slice(value);
    }
    Ok(())
}

/// `n` tightly packed items of `size` bytes at `offset` in `view`, checked to lie inside it.
fn section<'b>(
    view: &gltf::buffer::View,
    offset: usize,
    n: usize,
    size: usize,
    what: &'static str,
    buffers: &'b [gltf::buffer::Data],
) -> Result<&'b [u8], AccessorProblem> {
    let bytes = view_bytes(view, buffers)?;
    n.checked_mul(size)
        .and_then(|len| offset.checked_add(len))
        .and_then(|end| bytes.get(offset..end))
        .ok_or(AccessorProblem::SectionPastView {
            what,
            n,
            size,
            offset,
            view: view.index(),
            view_bytes: bytes.len(),
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normalized_components_decode_per_the_spec() {
        let d = decoder(DataType::I8, true);
        assert_eq!(d(&[127]), 1.0);
        assert_eq!(d(&[0x81]), -1.0); // -127
        assert_eq!(d(&[0x80]), -1.0); // -128 clamps
        assert_eq!(decoder(DataType::U8, true)(&[255]), 1.0);
        assert_eq!(
            decoder(DataType::I16, true)(&(-32768i16).to_le_bytes()),
            -1.0
        );
        assert_eq!(
            decoder(DataType::I16, true)(&16384i16.to_le_bytes()),
            16384.0 / 32767.0
        );
        assert_eq!(decoder(DataType::U16, true)(&65535u16.to_le_bytes()), 1.0);
        assert_eq!(
            decoder(DataType::I16, false)(&(-300i16).to_le_bytes()),
            -300.0
        );
        assert_eq!(decoder(DataType::U16, false)(&300u16.to_le_bytes()), 300.0);
        assert_eq!(unsigned(&70000u32.to_le_bytes()), 70000);
    }
}
