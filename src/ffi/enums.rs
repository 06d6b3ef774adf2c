//! The enumerations of the C API.
//!
//! Each is declared twice: a `#[repr(u32)]` Rust enum, which cbindgen emits
//! as the C `enum` listing the values, and a `u32` alias with the C name,
//! used in every signature and struct field. A C caller can pass any
//! integer, so Rust never reads these as an enum type: values are
//! converted with `from_raw` and unknown ones are rejected with
//! `PMC_STATUS_INVALID_ARGUMENT`.

use crate::{NormalMode, Reconstruction, Rule, ScalarType, Topology};

macro_rules! raw_enum {
    ($t:ident: $($v:ident),* $(,)?) => {
        impl $t {
            /// Every value, in numeric order.
            pub const ALL: &'static [$t] = &[$($t::$v),*];

            /// The value for a raw integer, `None` for an unknown one.
            pub fn from_raw(value: u32) -> Option<Self> {
                Self::ALL.iter().copied().find(|v| *v as u32 == value)
            }
        }
    };
}

/// Element type of the samples of a `pmc_volume` (VTK's scalar types).
/// Stored in C as a `uint32_t` holding one of the `PMC_SCALAR_TYPE_*`
/// values.
#[repr(u32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PmcScalarType {
    /// `int8_t` / `signed char`.
    I8 = 0,
    /// `uint8_t` / `unsigned char`.
    U8 = 1,
    /// `int16_t` / `short`.
    I16 = 2,
    /// `uint16_t` / `unsigned short`.
    U16 = 3,
    /// `int32_t` / `int`.
    I32 = 4,
    /// `uint32_t` / `unsigned int`.
    U32 = 5,
    /// `int64_t` / `long long`.
    I64 = 6,
    /// `uint64_t` / `unsigned long long`.
    U64 = 7,
    /// `float` (32-bit IEEE 754).
    F32 = 8,
    /// `double` (64-bit IEEE 754).
    F64 = 9,
}
raw_enum!(PmcScalarType: I8, U8, I16, U16, I32, U32, I64, U64, F32, F64);

/// The C representation of [`PmcScalarType`].
pub type pmc_scalar_type = u32;

impl PmcScalarType {
    /// The core element type.
    pub fn to_core(self) -> ScalarType {
        match self {
            PmcScalarType::I8 => ScalarType::I8,
            PmcScalarType::U8 => ScalarType::U8,
            PmcScalarType::I16 => ScalarType::I16,
            PmcScalarType::U16 => ScalarType::U16,
            PmcScalarType::I32 => ScalarType::I32,
            PmcScalarType::U32 => ScalarType::U32,
            PmcScalarType::I64 => ScalarType::I64,
            PmcScalarType::U64 => ScalarType::U64,
            PmcScalarType::F32 => ScalarType::F32,
            PmcScalarType::F64 => ScalarType::F64,
        }
    }
}

/// How ambiguous cells are triangulated. Stored in C as a `uint32_t`
/// holding one of the `PMC_TOPOLOGY_*` values.
#[repr(u32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PmcTopology {
    /// Inside every cell the mesh has the topology of the isosurface of the
    /// trilinear interpolant (the default).
    Trilinear = 0,
    /// The case table of `vtkMarchingCubes`: with refinement off the output
    /// is the surface `vtkMarchingCubes` produces. Refined, a cell whose
    /// table patch joins the crossings otherwise than the trilinear
    /// interpolant is split on its faces' edges only.
    Classic = 1,
}
raw_enum!(PmcTopology: Trilinear, Classic);

/// The C representation of [`PmcTopology`].
pub type pmc_topology = u32;

impl PmcTopology {
    /// The core mode.
    pub fn to_core(self) -> Topology {
        match self {
            PmcTopology::Trilinear => Topology::Trilinear,
            PmcTopology::Classic => Topology::Classic,
        }
    }
}

/// Where a triangle is sampled to decide whether to split it. Stored in C
/// as a `uint32_t` holding one of the `PMC_RULE_*` values.
#[repr(u32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PmcRule {
    /// Edge midpoints only: 1-, 2- or 3-edge splits.
    A = 0,
    /// Rule A, then the centroid when no edge splits (the default).
    A1 = 1,
    /// Rule A, then always a fourth point near the centroid.
    A2 = 2,
    /// The three edge midpoints and the centroid, tested at once.
    B = 3,
}
raw_enum!(PmcRule: A, A1, A2, B);

/// The C representation of [`PmcRule`].
pub type pmc_rule = u32;

impl PmcRule {
    /// The core rule.
    pub fn to_core(self) -> Rule {
        match self {
            PmcRule::A => Rule::A,
            PmcRule::A1 => Rule::A1,
            PmcRule::A2 => Rule::A2,
            PmcRule::B => Rule::B,
        }
    }
}

/// Which per-point normals to compute. Stored in C as a `uint32_t`
/// holding one of the `PMC_NORMALS_*` values.
#[repr(u32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PmcNormals {
    /// No normals: `pmc_mesh_normals` returns `NULL` (the default).
    None = 0,
    /// The exact gradient of the trilinear interpolant at the point,
    /// negated and normalised, in world space (at a point on a sample whose
    /// cell is flat there, as in a label volume contoured at a label's
    /// value, the central differences instead).
    Gradient = 1,
    /// As VTK: central-difference gradients at the grid points, interpolated
    /// trilinearly, negated and normalised.
    CentralDifference = 2,
}
raw_enum!(PmcNormals: None, Gradient, CentralDifference);

/// The C representation of [`PmcNormals`].
pub type pmc_normals = u32;

impl PmcNormals {
    /// The core mode.
    pub fn to_core(self) -> NormalMode {
        match self {
            PmcNormals::None => NormalMode::None,
            PmcNormals::Gradient => NormalMode::Gradient,
            PmcNormals::CentralDifference => NormalMode::CentralDifference,
        }
    }
}

/// The reconstruction filter refinement follows (see `Reconstruction` in
/// the README). Stored in C as a `uint32_t` holding one of the
/// `PMC_RECONSTRUCTION_*` values.
#[repr(u32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PmcReconstruction {
    /// The trilinear interpolant of each cell (the paper's; the default).
    Trilinear = 0,
    /// Tricubic Catmull-Rom: interpolating, C1.
    CatmullRom = 1,
    /// Tricubic B-spline of the samples: C2, smoothing.
    Bspline = 2,
    /// Tricubic B-spline through the samples (prefiltered; one `double`
    /// per sample of extra memory): C2, interpolating.
    BsplineInterpolating = 3,
}
raw_enum!(PmcReconstruction: Trilinear, CatmullRom, Bspline, BsplineInterpolating);

/// The C representation of [`PmcReconstruction`].
pub type pmc_reconstruction = u32;

impl PmcReconstruction {
    /// The core filter.
    pub fn to_core(self) -> Reconstruction {
        match self {
            PmcReconstruction::Trilinear => Reconstruction::Trilinear,
            PmcReconstruction::CatmullRom => Reconstruction::CatmullRom,
            PmcReconstruction::Bspline => Reconstruction::BSpline,
            PmcReconstruction::BsplineInterpolating => Reconstruction::BSplineInterpolating,
        }
    }
}
