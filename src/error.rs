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
    /// The number of samples does not fit in memory addressing.
    #[error("dimensions {0:?} overflow the addressable sample count")]
    DimensionOverflow([u64; 3]),
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
    /// A memory reservation failed.
    #[error("out of memory while reserving {0} bytes")]
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
