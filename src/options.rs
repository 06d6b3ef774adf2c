//! Extraction options: topology mode, refinement rule and limits.

/// How ambiguous cells are triangulated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Topology {
    /// Inside every cell the mesh has the topology of the isosurface of the
    /// trilinear interpolant (asymptotic decider on faces, interior
    /// connectivity from the exact trilinear function, tunnels included).
    /// Cells without ambiguity use the same triangles as `Classic`. The
    /// default.
    #[default]
    Trilinear,
    /// The case table of `vtkMarchingCubes`: with refinement off the output
    /// is the surface `vtkMarchingCubes` produces. Refined, a cell whose
    /// table patch joins the crossings otherwise than the trilinear
    /// interpolant is split on its faces' edges only (its interior could
    /// never reach the interpolant's isosurface).
    Classic,
}

/// Where a triangle is sampled to decide whether to split it
/// (section 3.1 of the paper).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Rule {
    /// Edge midpoints only: 1-, 2- or 3-edge splits.
    A,
    /// Rule A, then the centroid in a second phase when no edge splits. The
    /// default.
    #[default]
    A1,
    /// Rule A, then always a fourth point in a second phase: the centroid
    /// moved by the mean displacement of the edge points that were
    /// relocated onto the surface (our reading of the paper's Fig. 5).
    A2,
    /// The three midpoints and the centroid, all tested at once.
    B,
}

impl Rule {
    /// The most triangles one split makes of a triangle: four (three edge
    /// midpoints) under rules A and A1, whose centroid only ever comes
    /// alone; six (the midpoints and a fourth point) under A2 and B. A
    /// Marching Cubes triangle refined to level `l` has at most this to
    /// the power `l` leaves.
    pub(crate) fn most_children(self) -> u64 {
        match self {
            Rule::A | Rule::A1 => 4,
            Rule::A2 | Rule::B => 6,
        }
    }
}

/// Which normals to compute for the output points. Unit vectors in
/// float32, or `[0, 0, 0]` where the gradient they are made from vanishes
/// (central differences that cancel, common on data of two values, as in
/// VTK's filters); a component smaller than `f32::EPSILON` is written as 0 (it is
/// rounding noise, and would otherwise depend on how the point's position
/// rounded, e.g. for an extent not starting at 0).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum NormalMode {
    /// No normals. The default.
    #[default]
    None,
    /// The exact gradient of the trilinear interpolant at the point
    /// (negated and normalised, in world space). A point on a sample takes
    /// the cell on its upper side; where that cell's gradient is zero there
    /// (a label volume contoured at a label's value), the central
    /// differences of [`NormalMode::CentralDifference`] instead.
    Gradient,
    /// Like VTK: central-difference gradients at the grid points (one-sided
    /// at the border), interpolated trilinearly to the point, negated and
    /// normalised.
    CentralDifference,
}

/// The reconstruction filter whose isosurface refinement follows (split
/// points are moved onto its isosurface). Marching Cubes' topology always
/// comes from the samples (the trilinear decision); when refining with a
/// cubic filter, its edge vertices first move along their grid edge onto
/// the filter's isosurface (where the filter brackets one there).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Reconstruction {
    /// The trilinear interpolant of each cell (the paper's filter). The
    /// default.
    #[default]
    Trilinear,
    /// Tricubic Catmull–Rom: interpolating, C1, exact on quadratics away
    /// from the volume's border (each cubic filter reads a 4x4x4
    /// neighbourhood, with the border samples repeated beyond the volume:
    /// in the border cells it is none of these; a plane there is off by
    /// up to about 0.06 cells).
    CatmullRom,
    /// Tricubic B-spline of the samples: C2, smoothing (does not pass
    /// through the samples), exact on linear functions away from the
    /// volume's border (there, as for [`Reconstruction::CatmullRom`]: a
    /// plane is off by up to about 0.13 cells in the border cells).
    BSpline,
    /// Tricubic B-spline through the samples (prefiltered coefficients,
    /// one `f64` copy of the volume): C2 and interpolating (the border as
    /// for [`Reconstruction::CatmullRom`]).
    BSplineInterpolating,
}

/// Options of one extraction. `Options::default()` gives the documented
/// defaults.
#[derive(Debug, Clone, PartialEq)]
pub struct Options {
    /// Largest allowed distance, in cell-edge units of index space, between
    /// a tested sample point and the ideal surface. Default 0.01.
    /// `0` turns refinement off (plain Marching Cubes).
    pub epsilon: f64,
    /// Maximum refinement level (0 = plain Marching Cubes). Default 5, at
    /// most [`crate::MAX_LEVEL_LIMIT`].
    pub max_level: u32,
    /// Refinement rule. Default [`Rule::A1`].
    pub rule: Rule,
    /// Topology mode. Default [`Topology::Trilinear`].
    pub topology: Topology,
    /// Normals to compute. Default [`NormalMode::None`].
    pub normals: NormalMode,
    /// Whether to compute the gradient of the scalar field at each output
    /// point ([`crate::Mesh::gradients`], as `vtkFlyingEdges3D`'s
    /// `ComputeGradients`): un-normalised, pointing towards higher values,
    /// in sample value per world length unit (the index-space gradient
    /// divided by the spacing per axis). Computed as the normals are: by
    /// [`NormalMode::CentralDifference`] in that mode, else by the exact
    /// trilinear gradient of [`NormalMode::Gradient`], so that with both
    /// requested each normal is its point's negated, normalised gradient
    /// (to float32 rounding). Default `false`.
    pub gradients: bool,
    /// Cap on output triangles: refinement stops at the highest level whose
    /// output fits ([`crate::Stats::budget_reached`] then says so). The
    /// Marching Cubes triangles are always kept, so a cap below their count
    /// is exceeded. 0 = no cap of the caller's (the internal safety cap
    /// [`crate::HARD_TRIANGLE_CAP`] still applies). Default 0.
    pub max_triangles: u64,
    /// The most worker threads; 0 = all cores. Default 0. Values above
    /// [`crate::MAX_THREADS`] are clamped. The output does not depend on it.
    /// The calling thread works beside `threads - 1` helper threads, which
    /// are kept between calls (a call that finds them busy with another
    /// call starts helpers of its own and joins them before it returns;
    /// kept ones watch for work for 0.3 ms, then parked;
    /// each returns after 1 s without work, and
    /// [`crate::release_retained_memory`] stops them at once). Plain
    /// Marching Cubes (no refinement) of a volume under 32 768 cells runs
    /// on the calling thread alone, and a larger one gives each worker at
    /// least 16 384 cells: handing less work to a helper and joining the
    /// slabs costs more than it saves. Where
    /// threads cannot be started (a limit on threads), the call runs on
    /// those that did start, the calling thread at least.
    pub threads: usize,
    /// The filter refinement follows. Default [`Reconstruction::Trilinear`].
    pub reconstruction: Reconstruction,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            epsilon: 0.01,
            max_level: 5,
            rule: Rule::A1,
            topology: Topology::Trilinear,
            normals: NormalMode::None,
            gradients: false,
            max_triangles: 0,
            threads: 0,
            reconstruction: Reconstruction::Trilinear,
        }
    }
}

impl Options {
    /// Options for plain Marching Cubes (refinement off) in the given mode.
    pub fn marching_cubes(topology: Topology) -> Self {
        Options {
            epsilon: 0.0,
            max_level: 0,
            topology,
            ..Options::default()
        }
    }

    /// Whether these options refine at all.
    pub fn refines(&self) -> bool {
        self.epsilon > 0.0 && self.max_level > 0
    }
}
