//! Refining one cell's Marching Cubes patch onto `S_K` inside a slab pass
//! ([`crate::slab_pass`]): the cell settled by the bounds of
//! [`crate::near_bound`] when it can be, else its polygons re-cut
//! ([`crate::diagonals`]) and its triangles refined ([`Refiner`]) in up to
//! three attempts until the patch is sound, and the cell meshed again on
//! sub-cells when refinement stalls ([`crate::cell_remesh`]). The refined
//! points are welded as they are made: inside the cell by a small map of
//! its own, on its faces by the slab's.

use std::ops::ControlFlow;
use std::sync::atomic::Ordering;
use std::time::Instant;

use glam::DVec3;

use crate::cell_remesh::{count_remeshed, drop_patch, remesh_cell, CellAt};
use crate::diagonals::choose_diagonals;
use crate::filter::ReconstructionFilter;
use crate::flat_map::FlatMap;
use crate::mc::topology_check::classic_is_trilinear;
use crate::mc::Patch;
use crate::near_bound;
use crate::options::Topology;
use crate::point_key::{key, KeyMap};
use crate::refine::{
    edge_key, faces_like_marching_cubes, shared_fixed_axes, sound_patch, soundly_connected,
    vector_area, EdgeCache, Refinable, Refiner, Sample, Tri,
};
use crate::slab_pass::{
    note_flat, produced, report_emitted, strictly_inside, Mode, Shared, SlabOut,
};
use crate::subcells;
use crate::volume::Scalar;

/// How many refined cells of a slab are all timed before only one in
/// eight is (see [`SlabOut::refine_time`]).
const TIMED_CELLS: u64 = 64;

/// The most leaves a refined cell's patch can have (its Marching Cubes
/// triangles times [`crate::options::Rule::most_children`] to the power
/// max_level) for which the slab's buffers are reserved for the whole
/// patch before refining it (fallibly; see [`reserve_patch`]).
const CELL_RESERVE_LIMIT: u64 = 1 << 16;

/// Squared twice-area (local cell units) below which a refined triangle
/// counts as having no area (see the attempts in [`refine_cell`]); refined
/// triangles of a unit cell are many orders of magnitude larger.
const MIN_DOUBLE_AREA2: f64 = 1e-28;

/// Leaves a refined cell may make beyond what is left under the cap when
/// it may be meshed again on sub-cells (its stalled patch is replaced,
/// often by a smaller one; see [`crate::subcells`]).
const STALL_SLACK: u64 = 1 << 20;

/// The attempts at a sound patch, each only when the previous one gave an
/// unsound patch: first, interior samples whose gradient line leaves the
/// cell split at the nearest point of `S_K` inside the cell (see
/// [`Refiner::interior_fallback`]); second, they stay unsplit; third,
/// interior edges and centres stay whole. Edges on the cell's faces decide
/// alike in every attempt, so neighbours still match.
const ATTEMPTS: usize = 3;

/// A cell whose Marching Cubes patch is refined: its corner samples
/// (`corners`, VTK order) and those less the isovalue (`f`), its case,
/// whether its patch has interior points (an ambiguous cell's), its index
/// in the slab's grid and its lowest corner in global index coordinates,
/// and the filter's cell when the crossings already loaded it.
pub(crate) struct CellInput<'a, F: ReconstructionFilter> {
    pub corners: &'a [f64; 8],
    pub f: &'a [f64; 8],
    pub case: u8,
    pub interior_points: bool,
    pub ijk: [usize; 3],
    pub cell_f: DVec3,
    pub filter: Option<F::Cell>,
}

/// Buffers a slab pass reuses from cell to cell to refine them. `kept`
/// and `pos_of` are the cell's input: its Marching Cubes triangles (point
/// ids) and their corners' local positions, three a triangle, filled by
/// the pass before [`refine_cell`].
pub(crate) struct CellScratch {
    pub kept: Vec<[u32; 3]>,
    pub pos_of: Vec<DVec3>,
    /// The points made inside the open cell (see the welding in
    /// [`run_attempt`]).
    local: KeyMap<u32>,
    /// For the Classic topology's check (`mc::topology_check`).
    check: Patch,
    cache: EdgeCache,
    /// The edge tests the diagonals' choice ran, handed to the refiner.
    tested: Vec<(u32, u32, Sample)>,
    /// How many of the patch's triangles use each edge (by `edge_key`).
    uses: Vec<(u64, u8)>,
    /// The soundness check's edge map.
    edges: FlatMap<u32>,
    /// The patch's points that a weld from outside the cell has met.
    seen: FlatMap<()>,
    /// In a pass that only counts: the leaves (ids, local positions,
    /// levels), kept to mesh a stalled cell again.
    count_leaves: Vec<([u32; 3], [DVec3; 3], u8)>,
}

impl CellScratch {
    pub fn new() -> Self {
        CellScratch {
            kept: Vec::with_capacity(16),
            pos_of: Vec::with_capacity(16),
            local: KeyMap::default(),
            check: Patch::default(),
            cache: EdgeCache::default(),
            tested: Vec::with_capacity(16),
            uses: Vec::with_capacity(48),
            edges: FlatMap::default(),
            seen: FlatMap::default(),
            count_leaves: Vec::new(),
        }
    }
}

/// Refines the cell `cell` of the slab pass whose output is `out` (`map`
/// welds the points on cell faces, `reported` is what the pass has added
/// to the shared count): its patch (in `rs.kept` and `rs.pos_of`) goes to
/// `out` refined, and is counted. `Break` when the pass must stop (over
/// the cap, stopped, or out of memory: `out.scratch_failed` says so).
pub(crate) fn refine_cell<T: Scalar, F: ReconstructionFilter>(
    sh: &Shared<'_, T, F>,
    out: &mut SlabOut,
    map: &mut KeyMap<u32>,
    reported: &mut u64,
    mode: Mode,
    cell: CellInput<'_, F>,
    rs: &mut CellScratch,
) -> ControlFlow<()> {
    let count_only = matches!(mode, Mode::Count { .. });
    let (Mode::Output { cap } | Mode::Count { cap }) = mode;
    let opts = sh.options;
    let cell_f = cell.cell_f;
    out.mc_tris += rs.kept.len() as u64;
    // Two clock reads cost about 0.1 us on a virtual machine, a few per
    // cent of a lightly refined cell: the first cells of a slab are timed,
    // then one in eight.
    let timed = out.refined_cells < TIMED_CELLS || out.refined_cells % 8 == 0;
    let tr = timed.then(Instant::now);
    let Some(fc) = cell.filter.or_else(|| sh.filter.load(cell.ijk)) else {
        out.nonfinite += 1;
        return ControlFlow::Continue(());
    };
    // Under a cap, the leaves this cell may add before the pass is over it
    // for sure (the other slabs' count lags behind): past it the cell
    // reports at its end, where its final patch decides. The refinement of
    // one attempt stops only past the cap itself (and, for a cell that may
    // be meshed again on sub-cells, room for its stalled patch, which is
    // replaced): an attempt may still be dropped for a smaller one (see the
    // attempts below), and what is left of the cap depends on how far the
    // other slabs have got, so stopping there made the level a cap lowers
    // to depend on the thread count.
    let produced_before = produced(out, count_only);
    let (remaining, leaf_budget) = if cap == u64::MAX {
        (u64::MAX, u64::MAX)
    } else {
        let unreported = produced_before - *reported;
        let r = cap.saturating_sub(sh.emitted.load(Ordering::Relaxed) + unreported);
        let slack = if sh.subcells { STALL_SLACK } else { 0 };
        (r, cap.saturating_add(slack))
    };
    let end = CellEnd {
        t_start: out.tris.len(),
        timer: tr,
        produced_before,
        remaining,
    };
    // Interior edges split only in cells free of ties (a sample at the
    // isovalue is none for the trilinear filter: see `Refinable`).
    let mut refinable = Refinable::of_cell(cell.f, F::MULTILINEAR && F::LINEAR_ON_EDGES);
    // A table patch that joins the crossings otherwise than `S_K` can never
    // be refined onto it: its faces' edges only (see `mc::topology_check`).
    if opts.topology == Topology::Classic
        && !classic_is_trilinear(cell.case, cell.f, &mut rs.check.tris, &mut rs.check.extra)
    {
        refinable.interior = false;
        out.counters.unsound_cells += 1;
    }
    if let Some(samples) = settled(sh, &cell, &refinable, count_only, rs) {
        // Every test at level 0 would find its sample near: the cell keeps
        // its Marching Cubes triangles, emitted as refinement would.
        let n = rs.kept.len() as u64;
        if n > leaf_budget {
            sh.over_cap.store(true, Ordering::Relaxed);
            return ControlFlow::Break(());
        }
        out.tris.extend_from_slice(&rs.kept);
        out.levels.resize(out.levels.len() + rs.kept.len(), 0);
        out.counters.samples += samples;
        out.counters.per_level[0] += n;
        out.counters.nodes_per_level[0] += n;
        sh.poll_timed();
        return stop_if(refined_cell_done(sh, out, count_only, end, reported, cap));
    }
    // Polygons whose table diagonals refinement cannot follow are re-cut
    // first (see `diagonals`).
    rs.tested.clear();
    if refinable.interior {
        out.counters.recut_polygons += choose_diagonals::<F>(
            &fc,
            refinable.iso(sh.iso, 0, DVec3::ZERO),
            opts.epsilon,
            &mut rs.kept,
            &mut rs.pos_of,
            &mut rs.tested,
        ) as u64;
    }
    // Boundary edges of the cell's patch lie on cell faces.
    rs.uses.clear();
    for t in &rs.kept {
        for e in 0..3 {
            let key = edge_key(t[e], t[(e + 1) % 3]);
            match rs.uses.iter_mut().find(|u| u.0 == key) {
                Some(u) => u.1 += 1,
                None => rs.uses.push((key, 1)),
            }
        }
    }
    let (t_start, v_start) = (out.tris.len(), out.verts.len());
    let before = out.counters.clone();
    rs.local.clear();
    // (`reserved`: the leaves reserved for, which a debug assertion checks
    // the patch against.)
    let reserved = if count_only {
        usize::MAX
    } else {
        match reserve_patch(out, map, rs.kept.len(), sh.max_level, opts.rule) {
            Ok(n) => n,
            Err(bytes) => {
                out.scratch_failed = bytes;
                return ControlFlow::Break(());
            }
        }
    };
    for attempt in 0..ATTEMPTS {
        let nearest_before = out.counters.nearest_splits;
        let job = Job {
            fc: &fc,
            refinable: if attempt < ATTEMPTS - 1 {
                refinable
            } else {
                Refinable {
                    interior: false,
                    ..refinable
                }
            },
            leaf_budget,
            cell_f,
            v_start,
            count_only,
            attempt,
        };
        let made = run_attempt(sh, out, map, rs, &job)?;
        // Nearest points (of samples near a face, or off the band along
        // the faces) can land within rounding of each other without
        // welding: a triangle with no area means this attempt's nearest
        // splits are undone.
        let slivered = made.sliver && out.counters.nearest_splits != nearest_before;
        // The soundness check's edge map could not grow.
        let mut check_failed = 0;
        let accept = count_only
            || attempt == ATTEMPTS - 1
            || !refinable.interior
            || (!slivered
                && if made.merged {
                    // A nearest point may weld with another point into a
                    // vertex where the patch touches itself, which the
                    // checks below do not see.
                    out.counters.nearest_splits == nearest_before
                        && sound_patch(
                            cell_f,
                            &out.tris[t_start..],
                            &out.verts,
                            &rs.pos_of,
                            &mut rs.edges,
                        )
                        .unwrap_or_else(|bytes| {
                            check_failed = bytes;
                            true
                        })
                } else {
                    debug_assert!(
                        soundly_connected(&out.tris[t_start..], &mut rs.edges) != Ok(false),
                        "a patch without merged points is a subdivision"
                    );
                    faces_like_marching_cubes(made.area, &rs.pos_of)
                });
        if check_failed != 0 {
            out.scratch_failed = check_failed;
            return ControlFlow::Break(());
        }
        if accept {
            break;
        }
        drop_patch(out, map, &mut rs.local, t_start, v_start, None);
        let samples = out.counters.samples;
        out.counters = before.clone();
        out.counters.samples = samples;
        if attempt + 2 == ATTEMPTS {
            out.counters.unsound_cells += 1;
        }
    }
    debug_assert!(
        out.tris.len() - t_start <= reserved,
        "a patch of {} leaves outgrew its reservation of {reserved}",
        out.tris.len() - t_start
    );
    // A patch still far from S_K with long edges at the last level:
    // refinement stalled on a fold; mesh the cell again on sub-cells,
    // joined to the outline drawn above.
    if sh.subcells && out.counters.stalled_leaves > before.stalled_leaves {
        let at = CellAt {
            f: cell.f,
            cell_f,
            t_start,
            v_start,
            above_before: before.above_eps,
        };
        // Polled as refinement is: progress and the stop request (the
        // nested extraction and the outlines of a large patch take
        // seconds).
        let tick = || sh.poll_timed();
        let poll = subcells::Poll::new(
            sh.cancel,
            sh.poll.is_some().then_some(&tick as &(dyn Fn() + Sync)),
        );
        if count_only {
            count_remeshed(out, &rs.count_leaves, &at, opts, sh.max_level, &poll);
        } else {
            remesh_cell(out, map, &mut rs.local, &at, opts, sh.max_level, &poll);
        }
        if sh.cancel.load(Ordering::Relaxed) {
            // Stopped (the pass's output is dropped).
            return ControlFlow::Break(());
        }
    }
    sh.poll_timed();
    stop_if(refined_cell_done(sh, out, count_only, end, reported, cap))
}

/// `Break` when `stop`.
fn stop_if(stop: bool) -> ControlFlow<()> {
    if stop {
        ControlFlow::Break(())
    } else {
        ControlFlow::Continue(())
    }
}

/// The samples the level-0 tests of the cell would take, when the bounds
/// on the interpolant show that every one of them would find its sample
/// near and the unsplit patch passes the check a refined one would face
/// (see `near_bound`); `None` when the cell must be refined.
fn settled<T: Scalar, F: ReconstructionFilter>(
    sh: &Shared<'_, T, F>,
    cell: &CellInput<'_, F>,
    refinable: &Refinable,
    count_only: bool,
    rs: &CellScratch,
) -> Option<u64> {
    if !(F::MULTILINEAR
        && F::LINEAR_ON_EDGES
        && refinable.interior
        && refinable.shift[6] == 0.0
        && !count_only
        && sh.max_level > 0
        && !cell.interior_points)
    {
        return None;
    }
    let opts = sh.options;
    let far = cell.cell_f.abs().max_element();
    let (kept, pos_of) = (&rs.kept, &rs.pos_of);
    near_bound::all_near(
        cell.corners,
        sh.iso,
        far,
        kept,
        pos_of,
        opts.epsilon,
        opts.rule,
    )
    // The patch check the refined patch would face (unsplit, it fails
    // only when nearly flat).
    .filter(|_| {
        let area = pos_of
            .chunks_exact(3)
            .fold(DVec3::ZERO, |a, p| a + vector_area([p[0], p[1], p[2]]));
        faces_like_marching_cubes(area, pos_of)
    })
}

/// Room for a cell's whole refined patch of `triangles` Marching Cubes
/// triangles, reserved up front where its worst case is modest
/// (4^max_level leaves per Marching Cubes triangle under rules A and A1,
/// 6^max_level under A2 and B: up to level 6-8 or 4-6 by the cell's
/// triangles; the slab's map gets the points its boundary edges can split
/// into): the slab's buffers, the large allocations, then grow here, where
/// a failure is an error, and not while the patch is emitted, where it
/// would abort the process. The leaves reserved for (`usize::MAX` when
/// none were), or the bytes that could not be had.
fn reserve_patch(
    out: &mut SlabOut,
    map: &mut KeyMap<u32>,
    triangles: usize,
    max_level: u32,
    rule: crate::options::Rule,
) -> Result<usize, usize> {
    let level = max_level.min(31);
    let worst = (triangles as u64).saturating_mul(rule.most_children().saturating_pow(level));
    if worst > CELL_RESERVE_LIMIT {
        return Ok(usize::MAX);
    }
    let n = worst as usize;
    let on_faces = 3 * (triangles << level) + 16;
    try_room(&mut out.tris, n)
        .and_then(|_| try_room(&mut out.levels, n))
        .and_then(|_| try_room(&mut out.verts, n + 16))
        .and_then(|_| {
            map.try_reserve(on_faces).map_err(|_| {
                (map.len() + on_faces).max(2 * map.capacity()) * size_of::<([u64; 3], u32)>()
            })
        })?;
    Ok(n)
}

/// What one attempt refines a cell with: the filter's cell, which edges
/// may split, the leaves it may make, the cell's lowest corner (global
/// index coordinates), the slab's first point made for the cell, whether
/// the pass only counts, and the attempt's number (0: the first).
struct Job<'a, F: ReconstructionFilter> {
    fc: &'a F::Cell,
    refinable: Refinable,
    leaf_budget: u64,
    cell_f: DVec3,
    v_start: usize,
    count_only: bool,
    attempt: usize,
}

/// What an attempt's patch needs checked: whether refinement merged two of
/// the cell's points, whether a triangle has no area, and the patch's
/// vector area.
struct Attempt {
    merged: bool,
    sliver: bool,
    area: DVec3,
}

/// One attempt: refines each of the cell's Marching Cubes triangles (in
/// `rs.kept`), the leaves going to `out` (or, when only counting, counted
/// and kept in `rs.count_leaves`). `Break` when the pass must stop.
///
/// Whether refinement merged two of the cell's points (split points that
/// weld onto another point, which straight gradient lines meeting on `S_K`
/// can cause): each new point is created once (the edge cache hands its id
/// to the triangle on the other side), so any weld inside the cell, or
/// onto one of its Marching Cubes points, or twice onto the same point of
/// a neighbour, is a merge. Without one, the patch is a subdivision of the
/// Marching Cubes patch and only its facing needs checking.
fn run_attempt<T: Scalar, F: ReconstructionFilter>(
    sh: &Shared<'_, T, F>,
    out: &mut SlabOut,
    map: &mut KeyMap<u32>,
    rs: &mut CellScratch,
    job: &Job<'_, F>,
) -> ControlFlow<(), Attempt> {
    let opts = sh.options;
    let cell_f = job.cell_f;
    let v_start = job.v_start;
    rs.cache.clear();
    rs.count_leaves.clear();
    let mut merged = false;
    let mut sliver = false;
    let grow_failed = std::cell::Cell::new(0usize);
    let mut area = DVec3::ZERO;
    rs.seen.clear();
    for t in &rs.kept {
        for &v in t {
            rs.seen.insert_new(v as u64, ());
        }
    }
    // Distinct ids for new points when counting (the edge cache is keyed
    // by ids; 0..16 are the cell's own points).
    let mut next_id = 16u32;
    let tick = || sh.poll_timed();
    let mut refiner = Refiner::<F> {
        cell: job.fc,
        iso: sh.iso,
        epsilon: opts.epsilon,
        max_level: sh.max_level,
        rule: opts.rule,
        counters: &mut out.counters,
        cache: &mut rs.cache,
        interior_fallback: job.attempt == 0,
        leaf_budget: job.leaf_budget,
        stall_len2: if sh.subcells {
            subcells::stall_len2(sh.max_level)
        } else {
            f64::INFINITY
        },
        cancel: sh.cancel,
        polls: 0,
        tick: sh.poll.is_some().then_some(&tick as &(dyn Fn() + Sync)),
        alloc_failed: 0,
        refinable: job.refinable,
    };
    if job.attempt == 0 {
        // The diagonals' tests, already run to choose them.
        for (a, b, s) in &rs.tested {
            refiner.preset(*a, *b, s);
        }
    }
    let pos_of = &rs.pos_of;
    for (n, t) in rs.kept.iter().enumerate() {
        let p = [pos_of[3 * n], pos_of[3 * n + 1], pos_of[3 * n + 2]];
        let mut fixed = [0u8; 3];
        for e in 0..3 {
            let key = edge_key(t[e], t[(e + 1) % 3]);
            let boundary = rs.uses.iter().any(|u| u.0 == key && u.1 == 1);
            if boundary {
                fixed[e] = shared_fixed_axes(p[e], p[(e + 1) % 3]);
            }
        }
        let root = Tri {
            v: *t,
            p,
            fixed,
            level: 0,
            near: 0,
        };
        if job.count_only {
            // Leaves are kept only to mesh a stalled cell again (and count
            // that).
            let leaves = &mut rs.count_leaves;
            let within_budget = refiner.run(
                root,
                sh.subcells,
                &mut |t: &Tri| {
                    if sh.subcells {
                        leaves.push((t.v, t.p, t.level));
                    }
                },
                &mut |_| {
                    next_id += 1;
                    next_id
                },
            );
            if refiner.alloc_failed != 0 {
                out.scratch_failed = refiner.alloc_failed;
                return ControlFlow::Break(());
            }
            if !within_budget {
                // More leaves than the cap: the level does not fit,
                // whatever the rest counts (or the call was stopped, which
                // wins).
                sh.over_cap.store(true, Ordering::Relaxed);
                return ControlFlow::Break(());
            }
        } else {
            let verts = &mut out.verts;
            let (map, local) = (&mut *map, &mut rs.local);
            let (merged, area, seen) = (&mut merged, &mut area, &mut rs.seen);
            let sliver = &mut sliver;
            let tris = &mut out.tris;
            let levels = &mut out.levels;
            // Past the cell's reservation (a patch that may outgrow
            // CELL_RESERVE_LIMIT) the buffers grow fallibly: an allocation
            // that fails is recorded, nothing more is stored, and the pass
            // fails with OutOfMemory after this tree (an infallible push
            // aborted the host).
            let within_budget = refiner.run(
                root,
                true,
                &mut |tri: &Tri| {
                    if grow_failed.get() != 0 {
                        return;
                    }
                    if tris.len() == tris.capacity() || levels.len() == levels.capacity() {
                        let room = try_room(tris, tris.len().max(1024))
                            .and_then(|_| try_room(levels, levels.len().max(1024)));
                        if let Err(bytes) = room {
                            grow_failed.set(bytes);
                            return;
                        }
                    }
                    tris.push(tri.v);
                    levels.push(tri.level);
                    let a = vector_area(tri.p);
                    *sliver |= a.length_squared() < MIN_DOUBLE_AREA2;
                    *area += a;
                },
                &mut |p: DVec3| {
                    let gp = cell_f + p;
                    let next = verts.len() as u32;
                    // A point inside the open cell belongs to no other
                    // cell: a small per-cell map welds it (same ids, less
                    // memory traffic than the slab's map). Decided on the
                    // global coordinates: far from the origin, a point
                    // just inside the cell can round onto its face, where
                    // it must weld with the face's other points.
                    let inner = strictly_inside(gp, cell_f);
                    let m = if inner { &mut *local } else { &mut *map };
                    if grow_failed.get() != 0 {
                        return 0;
                    }
                    let room = if verts.len() == verts.capacity() {
                        try_room(verts, verts.len().max(1024))
                    } else {
                        Ok(())
                    }
                    .and_then(|_| {
                        m.try_reserve(1).map_err(|_| {
                            (2 * m.capacity().max(1024))
                                .saturating_mul(size_of::<([u64; 3], u32)>())
                        })
                    });
                    if let Err(bytes) = room {
                        grow_failed.set(bytes);
                        return 0;
                    }
                    let mut new = false;
                    let id = *m.entry(key(gp)).or_insert_with(|| {
                        new = true;
                        verts.push(gp);
                        next
                    });
                    if !new
                        && (inner
                            || id as usize >= v_start
                            || seen.insert_new(id as u64, ()).is_some())
                    {
                        *merged = true;
                    }
                    id
                },
            );
            let failed = grow_failed.get().max(refiner.alloc_failed);
            if failed != 0 {
                out.scratch_failed = failed;
                return ControlFlow::Break(());
            }
            if !within_budget {
                // Over the cap (or stopped): this pass's output is
                // dropped, stop here.
                sh.over_cap.store(true, Ordering::Relaxed);
                return ControlFlow::Break(());
            }
        }
    }
    ControlFlow::Continue(Attempt {
        merged,
        sliver,
        area,
    })
}

/// Where a refined cell's output starts and what the pass had produced
/// and had left under the cap before it (see [`refined_cell_done`]).
struct CellEnd {
    /// The cell's first triangle in the slab's output.
    t_start: usize,
    /// When the cell started, if it is one of the timed cells.
    timer: Option<Instant>,
    produced_before: u64,
    remaining: u64,
}

/// Ends a refined cell: notes its flat triangles, counts it (and its time
/// when timed), and reports the slab's output to the shared count when it
/// grew by many or by more than was left (one row of deeply refined cells
/// can hold far more than the cap). True when the pass is over the cap.
fn refined_cell_done<T: Scalar, F: ReconstructionFilter>(
    sh: &Shared<'_, T, F>,
    out: &mut SlabOut,
    count_only: bool,
    end: CellEnd,
    reported: &mut u64,
    cap: u64,
) -> bool {
    if !count_only {
        note_flat(out, end.t_start);
    }
    out.refined_cells += 1;
    if let Some(start) = end.timer {
        out.timed_refine += start.elapsed();
        out.timed_cells += 1;
    }
    let n = produced(out, count_only);
    (n - *reported >= 4096 || n - end.produced_before > end.remaining)
        && report_emitted(sh, n, reported, cap)
}

/// Reserves room for `n` more items in `v`; on failure, the bytes of the
/// buffer that could not be had (at least double the old one, as `Vec`
/// grows).
fn try_room<T>(v: &mut Vec<T>, n: usize) -> Result<(), usize> {
    v.try_reserve(n).map_err(|_| {
        v.len()
            .saturating_add(n)
            .max(v.capacity().saturating_mul(2))
            .saturating_mul(size_of::<T>())
    })
}
