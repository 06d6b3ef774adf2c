//! `pmc_volume`: the caller's samples, described field by field.

use std::ffi::c_void;

use super::enums::{pmc_scalar_type, PmcScalarType};
use super::panic::Failure;
use super::struct_size;
use crate::{Samples, Volume};

/// A regular grid of samples in memory owned by the caller, borrowed for
/// the duration of one `pmc_extract` call (nothing is copied or kept).
///
/// Sample `(i, j, k)`, with `0 <= i < dims[0]` and so on, is element
/// `i * strides[0] + j * strides[1] + k * strides[2]` of `data`, and lies
/// at world position `origin + spacing * (index_offset + (i, j, k))` per
/// axis, where `index_offset` is set with `pmc_options_set_index_offset`
/// (default 0). The isosurface is oriented with triangle normals pointing
/// towards lower values.
///
/// Every field is validated before any sample is read: an inconsistent
/// volume is `PMC_STATUS_INVALID_ARGUMENT` (`PMC_STATUS_NULL_ARGUMENT` for
/// `data == NULL`), never an out-of-bounds read.
///
/// Set `struct_size` to `sizeof(pmc_volume)` first (zero-initialise the
/// struct, then set the fields), so that later versions of the library
/// can append fields without breaking callers built against this header.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct pmc_volume {
    /// Size in bytes of the caller's struct: set it to
    /// `sizeof(pmc_volume)`. No default: 0, or less than the size of the
    /// first `pmc_volume` layout (128 bytes on 64-bit platforms), is
    /// `PMC_STATUS_INVALID_ARGUMENT`, checked before any other field is
    /// read. A larger value up to 65536 (a caller built against a later
    /// header) is accepted; the library reads only the fields it knows.
    /// Above 65536 it is rejected (likely a pointer: a caller built
    /// against a header without `struct_size`).
    pub struct_size: u64,
    /// First element of the samples; must be aligned for `scalar_type`.
    pub data: *const c_void,
    /// Number of elements (not bytes) readable from `data`. Every element
    /// addressed by `dims` and `strides` must be below `len`.
    pub len: u64,
    /// Element type of `data`: one of the `PMC_SCALAR_TYPE_*` values.
    pub scalar_type: pmc_scalar_type,
    /// Number of samples along x, y and z; each at least 2 and at most
    /// 2^40.
    pub dims: [u64; 3],
    /// Distance in elements (not bytes) between neighbouring samples along
    /// x, y and z. All zero means contiguous with x fastest, i.e.
    /// `{1, dims[0], dims[0] * dims[1]}`. Since `data` is the first
    /// addressed element, negative strides address memory before it and
    /// are rejected (the message names the axis and the stride). A zero
    /// stride on some axes but not all is rejected too: it would read one
    /// sample for a whole axis.
    pub strides: [i64; 3],
    /// World position of global sample index (0, 0, 0); finite.
    pub origin: [f64; 3],
    /// World distance between neighbouring samples along x, y and z;
    /// finite and > 0. The world box must be finite too: on each axis,
    /// `origin + spacing * index` must not overflow for the first and last
    /// global sample index (`index_offset` and `index_offset + dims - 1`).
    pub spacing: [f64; 3],
}

/// The volume at `p`, after checking `p` (`PMC_STATUS_NULL_ARGUMENT` for
/// `NULL`) and its `struct_size`, before reading any other field.
///
/// # Safety
///
/// `p` must be `NULL` or point to a `pmc_volume` readable for the
/// `struct_size` bytes it declares (at least its first 8 bytes).
pub(crate) unsafe fn volume_ref<'a>(p: *const pmc_volume) -> Result<&'a pmc_volume, Failure> {
    if p.is_null() {
        return Err(Failure::null("volume"));
    }
    // SAFETY: non-null, and readable for its first 8 bytes per the contract.
    unsafe { struct_size::check(p, "pmc_volume", struct_size::PMC_VOLUME_SIZE_V1)? };
    // SAFETY: readable for `struct_size` bytes, now known to cover this
    // library's `pmc_volume`.
    Ok(unsafe { &*p })
}

/// Builds a core volume over `v`'s samples, after checking the strides'
/// signs and everything a slice needs (non-null, aligned data; a byte
/// length that fits `isize`) and running [`Volume::validate`] (dims,
/// spacing, origin, every addressed element in `0..len`).
///
/// # Safety
///
/// `v.data` must be `NULL` or valid for reading `v.len` elements of
/// `v.scalar_type` for `'a`, not written meanwhile.
pub(crate) unsafe fn core_volume<'a>(
    v: &pmc_volume,
    index_offset: [i64; 3],
) -> Result<Volume<'a>, Failure> {
    // A NULL pointer first, whatever else is wrong, as documented (the
    // caller has checked `struct_size`, see [`volume_ref`]).
    if v.data.is_null() {
        return Err(Failure::null("volume->data"));
    }
    let ty = PmcScalarType::from_raw(v.scalar_type)
        .ok_or_else(|| Failure::invalid(format!("unknown scalar type {}", v.scalar_type)))?;
    // `data` is the lowest element addressed (there is no offset field as
    // in `Volume`, where a negative stride pairs with one): a negative
    // stride always reads before it. Said so, rather than as the negative
    // sample index `Volume::validate` would name.
    if let Some(axis) = v.strides.iter().position(|&s| s < 0) {
        return Err(Failure::invalid(format!(
            "invalid volume: stride {axis} is {}; strides must not be negative \
             (data is the lowest element addressed)",
            v.strides[axis]
        )));
    }
    // SAFETY: forwarded contract.
    let samples = unsafe { samples(ty, v.data, v.len)? };
    let volume = Volume::new(samples, v.dims)
        .with_strides(v.strides)
        .with_origin(v.origin)
        .with_spacing(v.spacing)
        .with_index_offset(index_offset);
    volume.validate().map_err(|e| match e {
        // Not a field of the volume: an option.
        crate::Error::InvalidIndexOffset { .. } => Failure::invalid(format!(
            "invalid options: {e} (pmc_options_set_index_offset)"
        )),
        _ => Failure::invalid(format!("invalid volume: {e}")),
    })?;
    Ok(volume)
}

/// A typed slice of `len` elements at `data`.
///
/// # Safety
///
/// `data` must be non-null and valid for reading `len` elements of `ty`.
unsafe fn samples<'a>(
    ty: PmcScalarType,
    data: *const c_void,
    len: u64,
) -> Result<Samples<'a>, Failure> {
    /// # Safety
    /// As for `samples`.
    unsafe fn slice<'a, T>(data: *const c_void, len: u64) -> Result<&'a [T], Failure> {
        let size = std::mem::size_of::<T>() as u128;
        if len as u128 * size > isize::MAX as u128 {
            return Err(Failure::invalid(format!(
                "volume->len {len} elements of {size} bytes exceed the address space"
            )));
        }
        if (data as usize) % std::mem::align_of::<T>() != 0 {
            return Err(Failure::invalid(format!(
                "volume->data {data:p} is not aligned for {}-byte elements",
                std::mem::align_of::<T>()
            )));
        }
        // SAFETY: `data` is non-null and aligned, the byte length fits
        // `isize`, and the caller guarantees `len` readable elements.
        Ok(unsafe { std::slice::from_raw_parts(data.cast::<T>(), len as usize) })
    }
    // SAFETY (all arms): forwarded contract.
    unsafe {
        Ok(match ty {
            PmcScalarType::I8 => Samples::I8(slice(data, len)?),
            PmcScalarType::U8 => Samples::U8(slice(data, len)?),
            PmcScalarType::I16 => Samples::I16(slice(data, len)?),
            PmcScalarType::U16 => Samples::U16(slice(data, len)?),
            PmcScalarType::I32 => Samples::I32(slice(data, len)?),
            PmcScalarType::U32 => Samples::U32(slice(data, len)?),
            PmcScalarType::I64 => Samples::I64(slice(data, len)?),
            PmcScalarType::U64 => Samples::U64(slice(data, len)?),
            PmcScalarType::F32 => Samples::F32(slice(data, len)?),
            PmcScalarType::F64 => Samples::F64(slice(data, len)?),
        })
    }
}
