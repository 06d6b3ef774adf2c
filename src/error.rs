//! The error type of every fallible call in the crate.

use thiserror::Error;

/// Why an extraction could not run: a caller mistake, a resource limit,
/// the caller's own stop ([`Error::Aborted`]) or a host executor that did
/// not run its tasks ([`Error::Executor`]); none is a panic.
///
/// Non-exhaustive: later versions may add variants (a `match` needs a
/// wildcard arm), so that a new way to fail is not a breaking change.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum Error {
    /// A dimension is below 2 (a volume needs at least one cell per axis).
    #[error("dimension {} is {value}; every dimension must be at least 2", Axis(*.axis))]
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
        "dimension {} is {value}; the limit is 2^40 = {limit} samples per axis",
        Axis(*.axis),
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
        "index offset {} is {value}; index offsets must lie in \
         -{limit}..={limit} (2^31)",
        Axis(*.axis),
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
        "the world coordinate {} of global index {index}, origin {} + \
         spacing {} * {index}, is not finite",
        Axis(*.axis),
        Number(*.origin),
        Number(*.spacing)
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
    #[error("spacing {} is {}; spacings must be finite and > 0", Axis(*.axis), Number(*.value))]
    InvalidSpacing {
        /// Axis index.
        axis: usize,
        /// The rejected spacing.
        value: f64,
    },
    /// An origin coordinate is not finite.
    #[error("origin {} is {}; the origin must be finite", Axis(*.axis), Number(*.value))]
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
    #[error("isovalue {} is not finite", Number(*.0))]
    InvalidIsovalue(f64),
    /// Epsilon is negative or not finite.
    #[error("epsilon {} must be finite and >= 0 (cell units)", Number(*.0))]
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
    /// A worker thread pool could not be created. No longer returned:
    /// where worker threads cannot start (a limit on threads), the
    /// extraction and the measure run on the threads that did, the
    /// calling thread at least. Kept so that matches on it still
    /// compile.
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
    /// A triangle given to [`crate::accuracy::measure`] names a point the
    /// mesh does not have.
    #[error(
        "invalid mesh for the distance measure: triangle {triangle} has point id {id}, \
         but the mesh has {points} points"
    )]
    PointIdOutOfRange {
        /// The triangle's position in the triangle array.
        triangle: usize,
        /// Its point id, `>= points`.
        id: u64,
        /// The number of points.
        points: usize,
    },
}

/// An axis in a message: its index and its name, `1 (y)`, so that a C
/// caller's `dims[1]` and a VTK user's y axis are both recognised.
pub(crate) struct Axis(pub usize);

impl std::fmt::Display for Axis {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match ["x", "y", "z"].get(self.0) {
            Some(name) => write!(f, "{} ({name})", self.0),
            None => write!(f, "{}", self.0),
        }
    }
}

/// A number in a message: as Rust prints it, but in scientific notation
/// when that would run to many digits (`1e308`, not 309 of them; `1e-300`,
/// not 300 zeros), so the message stays short enough for a C caller's
/// buffer.
pub(crate) struct Number(pub f64);

impl std::fmt::Display for Number {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let v = self.0;
        if v.is_finite() && v != 0.0 && !(1e-6..1e16).contains(&v.abs()) {
            write!(f, "{v:e}")
        } else {
            write!(f, "{v}")
        }
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_in_messages_stay_short() {
        let shown = |v: f64| Number(v).to_string();
        assert_eq!(shown(-3.0), "-3");
        assert_eq!(shown(0.5), "0.5");
        assert_eq!(shown(0.0), "0");
        assert_eq!(shown(f64::NAN), "NaN");
        assert_eq!(shown(f64::NEG_INFINITY), "-inf");
        assert_eq!(shown(1.7e308), "1.7e308");
        assert_eq!(shown(-1e-300), "-1e-300");
        assert_eq!(shown(123456.25), "123456.25");
        let e = Error::InvalidOrigin {
            axis: 1,
            value: f64::MAX,
        };
        assert!(e.to_string().len() < 80, "{e}");
    }
}
