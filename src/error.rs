//! The error type of every fallible call in the crate.

use thiserror::Error;

/// Why an extraction could not run. Every variant is a caller mistake or a
/// resource limit; none is a panic.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum Error {
    /// A dimension is below 2 (a volume needs at least one cell per axis).
    #[error("dimension {axis} is {value}; every dimension must be at least 2")]
    DimensionTooSmall {
        /// Axis index (0 = x, 1 = y, 2 = z).
        axis: usize,
        /// The rejected dimension.
        value: u64,
    },
    /// The number of samples does not fit in memory addressing (more than
    /// `isize::MAX`).
    #[error("dimensions {0:?} overflow the addressable sample count")]
    DimensionOverflow([u64; 3]),
    /// A dimension is above [`crate::MAX_DIMENSION`] (2^40 samples).
    #[error(
        "dimension {axis} is {value}; the limit is 2^40 = {limit} samples per axis",
        limit = crate::MAX_DIMENSION
    )]
    DimensionTooLarge {
        /// Axis index (0 = x, 1 = y, 2 = z).
        axis: usize,
        /// The rejected dimension.
        value: u64,
    },
    /// An index offset is outside `-2^31..=2^31` (see
    /// [`crate::MAX_INDEX_OFFSET`]).
    #[error(
        "index offset {axis} is {value}; index offsets must lie in \
         -{limit}..={limit} (2^31)",
        limit = crate::MAX_INDEX_OFFSET
    )]
    InvalidIndexOffset {
        /// Axis index (0 = x, 1 = y, 2 = z).
        axis: usize,
        /// The rejected offset, in samples.
        value: i64,
    },
    /// The world coordinate of the volume's first or last sample along an
    /// axis, `origin + spacing * index`, is not finite (it overflows).
    #[error(
        "the world coordinate {axis} of global index {index}, origin {origin} + \
         spacing {spacing} * {index}, is not finite"
    )]
    WorldOverflow {
        /// Axis index (0 = x, 1 = y, 2 = z).
        axis: usize,
        /// The global sample index (index offset included) whose world
        /// coordinate overflows.
        index: i64,
        /// The volume's origin on that axis.
        origin: f64,
        /// The volume's spacing on that axis.
        spacing: f64,
    },
    /// A spacing is zero, negative or not finite.
    #[error("spacing {axis} is {value}; spacings must be finite and > 0")]
    InvalidSpacing {
        /// Axis index.
        axis: usize,
        /// The rejected spacing.
        value: f64,
    },
    /// An origin coordinate is not finite.
    #[error("origin {axis} is {value}; the origin must be finite")]
    InvalidOrigin {
        /// Axis index.
        axis: usize,
        /// The rejected coordinate.
        value: f64,
    },
    /// The strides, offset and dimensions address samples outside the buffer.
    #[error("the volume addresses sample index {index}, outside the buffer of {len} samples")]
    OutOfBounds {
        /// The offending element index (may be negative).
        index: i128,
        /// Declared buffer length in elements.
        len: u64,
    },
    /// A stride is zero (every axis has at least two samples, so a zero
    /// stride would alias them; the all-zero shorthand of
    /// [`crate::Volume::with_strides`] means contiguous and is resolved
    /// before validation).
    #[error("invalid strides {0:?}: a stride of 0 aliases samples")]
    InvalidStrides([i64; 3]),
    /// The isovalue is NaN or infinite.
    #[error("isovalue {0} is not finite")]
    InvalidIsovalue(f64),
    /// Epsilon is negative or not finite.
    #[error("epsilon {0} must be finite and >= 0 (cell units)")]
    InvalidEpsilon(f64),
    /// The maximum refinement level is above [`crate::MAX_LEVEL_LIMIT`].
    #[error("max level {0} is above the limit of {limit}", limit = crate::MAX_LEVEL_LIMIT)]
    InvalidMaxLevel(u32),
    /// A memory reservation of this many bytes failed (`usize::MAX` when
    /// the size itself overflows).
    #[error("out of memory while reserving {}", reserved_bytes(*.0))]
    OutOfMemory(usize),
    /// The progress callback asked to stop.
    #[error("aborted by the progress callback")]
    Aborted,
    /// The host's executor (see [`crate::Executor`]) returned without
    /// running every task it was given.
    #[error("the executor ran {ran} of {total} tasks")]
    Executor {
        /// Tasks that ran.
        ran: usize,
        /// Tasks handed to it.
        total: usize,
    },
    /// A worker thread pool could not be created.
    #[error("cannot start worker threads: {0}")]
    ThreadPool(String),
    /// A cell or point outside the volume given to
    /// [`crate::filter::evaluate`].
    #[error("cell {cell:?} or local point {local:?} is outside the volume")]
    OutOfVolume {
        /// The cell asked for (local cell indices).
        cell: [u64; 3],
        /// The local point asked for.
        local: [f64; 3],
    },
    /// Invalid input to [`crate::accuracy::measure`] (the reason).
    #[error("invalid mesh or settings for the distance measure: {0}")]
    InvalidMeasure(&'static str),
}

/// The size in an out-of-memory message: sizes are saturated, so
/// `usize::MAX` stands for one beyond the address space.
fn reserved_bytes(n: usize) -> String {
    if n == usize::MAX {
        "more bytes than the address space holds".to_string()
    } else {
        format!("{n} bytes")
    }
}
