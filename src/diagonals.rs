//! The diagonals a cell's Marching Cubes polygons start refinement with.
//!
//! Marching Cubes cuts each polygon of a cell (a loop of edge crossings)
//! into triangles along diagonals chosen by the case table, blind to the
//! data. Where the surface hugs a cell face, the polygon's outline on that
//! face bends far from the chord between its crossings, and a diagonal
//! from the table can cut straight across the part of the cell the surface
//! never enters: its midpoint has no point of `S_K` near it inside the
//! cell (the nearest one lies on the cell's boundary), so refinement cannot
//! move it onto the surface and its triangle stays far away, at any
//! epsilon. Before refining, such a polygon is re-cut along the diagonals
//! that refinement can follow (an interval dynamic programme over the
//! polygon's triangulations). The choice is a pure function of the cell's
//! data, and the polygon's outline (its edges on the cell faces, which the
//! neighbour shares) never changes, so the mesh stays crack-free and
//! independent of threads and pieces. Polygons whose table diagonals all
//! reach the surface keep them, bit for bit.

use glam::DVec3;

use crate::filter::ReconstructionFilter;
use crate::refine::{sample_edge, shared_fixed_axes, Sample};

/// Polygons up to this many vertices are re-cut (an ambiguous cell's
/// disk has at most twelve crossings).
const MAX_POLYGON: usize = 12;

/// Triangles of one cell's patch considered (a disk of `MAX_POLYGON`
/// points has `MAX_POLYGON - 2`; tubes and fans are left alone).
const MAX_TRIS: usize = 2 * MAX_POLYGON;

/// What a diagonal costs: whether refinement cannot bring its midpoint
/// onto `S_K` (`stuck`), then its midpoint's distance to `S_K` along the
/// line refinement would move it.
#[derive(Clone, Copy, PartialEq, PartialOrd)]
struct Cost {
    stuck: u32,
    distance: f64,
}

impl Cost {
    const ZERO: Cost = Cost {
        stuck: 0,
        distance: 0.0,
    };

    fn add(self, o: Cost) -> Cost {
        Cost {
            stuck: self.stuck.saturating_add(o.stuck),
            distance: self.distance + o.distance,
        }
    }
}

/// A tested diagonal: its cost and the test's outcome (handed to the
/// refiner so the test is not run twice).
#[derive(Clone, Copy)]
struct Diagonal {
    cost: Cost,
    sample: Option<Sample>,
}

/// Tests the diagonal between local positions `a` and `b` exactly as the
/// refiner tests an interior edge at level 0.
fn diagonal<F: ReconstructionFilter>(
    cell: &F::Cell,
    iso: f64,
    epsilon: f64,
    a: DVec3,
    b: DVec3,
) -> Diagonal {
    if shared_fixed_axes(a, b) != 0 {
        // Flat in a cell face, where the neighbour's patch has its outline.
        return Diagonal {
            cost: Cost {
                stuck: u32::MAX / 4,
                distance: 0.0,
            },
            sample: None,
        };
    }
    let m = (a + b) * 0.5;
    let s = sample_edge::<F>(cell, iso, a, b, 0, epsilon, true);
    Diagonal {
        cost: Cost {
            stuck: s.stuck as u32,
            distance: s.split.map_or(0.0, |q| (q - m).length()),
        },
        sample: Some(s),
    }
}

/// Re-cuts the polygons of one cell's patch whose diagonals refinement
/// cannot follow (see the module docs), for a cell whose interior may be
/// refined. `tris` are the patch's triangles (point ids), `pos` their
/// corners' local positions, three per triangle, in the same order; both
/// are rewritten in place (same count). `tested` receives the final
/// diagonals' end points and outcomes, to preset in the refiner (see
/// [`crate::refine::Refiner::preset`]). Returns the number of polygons
/// re-cut.
pub(crate) fn choose_diagonals<F: ReconstructionFilter>(
    cell: &F::Cell,
    iso: f64,
    epsilon: f64,
    tris: &mut [[u32; 3]],
    pos: &mut [DVec3],
    tested: &mut Vec<(u32, u32, Sample)>,
) -> u32 {
    let m = tris.len();
    if !(2..=MAX_TRIS).contains(&m) {
        return 0;
    }
    // The triangle across each edge, if any.
    let mut twin = [[u8::MAX; 3]; MAX_TRIS];
    for x in 0..m {
        for e in 0..3 {
            let (a, b) = (tris[x][e], tris[x][(e + 1) % 3]);
            for y in x + 1..m {
                if let Some(f) = (0..3).find(|&f| tris[y][f] == b && tris[y][(f + 1) % 3] == a) {
                    twin[x][e] = y as u8;
                    twin[y][f] = x as u8;
                }
            }
        }
    }
    // Usually every diagonal reaches the surface: test each once (as the
    // refiner would) and keep the cut.
    let mut stuck = false;
    for x in 0..m {
        for e in 0..3 {
            if (twin[x][e] as usize) < x || twin[x][e] == u8::MAX {
                continue;
            }
            let d = diagonal::<F>(cell, iso, epsilon, pos[3 * x + e], pos[3 * x + (e + 1) % 3]);
            if let Some(s) = d.sample {
                tested.push((tris[x][e], tris[x][(e + 1) % 3], s));
            }
            stuck |= d.cost.stuck > 0;
        }
    }
    if !stuck {
        return 0;
    }
    // Triangles joined across shared edges form the patch's polygons.
    let mut seen = [false; MAX_TRIS];
    let mut recut = 0;
    for root in 0..m {
        if seen[root] {
            continue;
        }
        let mut members = [0u8; MAX_TRIS];
        seen[root] = true;
        members[0] = root as u8;
        let mut nt = 1;
        let mut k = 0;
        while k < nt {
            let x = members[k] as usize;
            k += 1;
            for &y in &twin[x] {
                if y != u8::MAX && !seen[y as usize] {
                    seen[y as usize] = true;
                    members[nt] = y;
                    nt += 1;
                }
            }
        }
        let members = &mut members[..nt];
        members.sort_unstable();
        if nt < 2 {
            continue;
        }
        recut += recut_polygon::<F>(cell, iso, epsilon, tris, pos, members, &twin, tested) as u32;
    }
    recut
}

/// One polygon of [`choose_diagonals`]: the triangles `members` (sorted).
#[allow(clippy::too_many_arguments)]
fn recut_polygon<F: ReconstructionFilter>(
    cell: &F::Cell,
    iso: f64,
    epsilon: f64,
    tris: &mut [[u32; 3]],
    pos: &mut [DVec3],
    members: &[u8],
    twin: &[[u8; 3]; MAX_TRIS],
    tested: &mut Vec<(u32, u32, Sample)>,
) -> bool {
    let nt = members.len();
    let n = nt + 2;
    if n > MAX_POLYGON {
        return false;
    }
    // The outline: directed edges without a twin, with their start's
    // position. A polygon cut by diagonals has n of them, forming one
    // cycle through n distinct points (a fan around an interior point or
    // a tube does not).
    let mut outline = [(0u32, 0u32, DVec3::ZERO); MAX_TRIS + 2];
    let mut nb = 0;
    let mut diagonals = [(0u32, 0u32); MAX_TRIS];
    let mut nd = 0;
    for &x in members {
        let x = x as usize;
        for e in 0..3 {
            let (a, b) = (tris[x][e], tris[x][(e + 1) % 3]);
            if twin[x][e] == u8::MAX {
                if nb == n {
                    return false;
                }
                outline[nb] = (a, b, pos[3 * x + e]);
                nb += 1;
            } else if a < b {
                diagonals[nd] = (a, b);
                nd += 1;
            }
        }
    }
    if nb != n {
        return false;
    }
    // Walk the outline from its first edge: ring[k] and its position.
    let mut ring = [0u32; MAX_POLYGON];
    let mut at = [DVec3::ZERO; MAX_POLYGON];
    let mut edge = outline[0];
    for k in 0..n {
        (ring[k], at[k]) = (edge.0, edge.2);
        match outline[..n].iter().find(|o| o.0 == edge.1) {
            Some(&o) => edge = o,
            None => return false,
        }
    }
    if edge.0 != ring[0] || (0..n).any(|a| (a + 1..n).any(|b| ring[a] == ring[b])) {
        return false;
    }
    let index = |v: u32| (0..n).find(|&k| ring[k] == v).unwrap_or(0);
    type Memo = [[Option<Diagonal>; MAX_POLYGON]; MAX_POLYGON];
    let mut memo: Memo = [[None; MAX_POLYGON]; MAX_POLYGON];
    let cost = |memo: &mut Memo, i: usize, j: usize| -> Diagonal {
        let (i, j) = (i.min(j), i.max(j));
        if j == i + 1 || (i == 0 && j == n - 1) {
            // A side of the polygon, not a diagonal.
            return Diagonal {
                cost: Cost::ZERO,
                sample: None,
            };
        }
        *memo[i][j].get_or_insert_with(|| diagonal::<F>(cell, iso, epsilon, at[i], at[j]))
    };
    let mut current = Cost::ZERO;
    for &(a, b) in &diagonals[..nd] {
        current = current.add(cost(&mut memo, index(a), index(b)).cost);
    }
    if current.stuck == 0 {
        return false;
    }
    // best[i][j]: the cheapest cut of the sub-polygon i..=j (closed by the
    // segment i-j), apex[i][j] the third corner of its triangle on i-j.
    let mut best = [[Cost::ZERO; MAX_POLYGON]; MAX_POLYGON];
    let mut apex = [[0u8; MAX_POLYGON]; MAX_POLYGON];
    for span in 2..n {
        for i in 0..n - span {
            let j = i + span;
            let mut b = (
                Cost {
                    stuck: u32::MAX,
                    distance: 0.0,
                },
                i + 1,
            );
            for k in i + 1..j {
                let c = best[i][k]
                    .add(best[k][j])
                    .add(cost(&mut memo, i, k).cost)
                    .add(cost(&mut memo, k, j).cost);
                if c < b.0 {
                    b = (c, k);
                }
            }
            best[i][j] = b.0;
            apex[i][j] = b.1 as u8;
        }
    }
    if best[0][n - 1].stuck >= current.stuck {
        return false;
    }
    // The old diagonals' tests go; the new ones' come below.
    tested.retain(|&(a, b, _)| !diagonals[..nd].contains(&(a.min(b), a.max(b))));
    // Write the new triangles over the polygon's old slots, each wound
    // like the outline.
    let mut stack = [(0usize, 0usize); MAX_POLYGON];
    stack[0] = (0, n - 1);
    let mut top = 1;
    let mut slot = 0;
    while top > 0 {
        top -= 1;
        let (i, j) = stack[top];
        if j < i + 2 {
            continue;
        }
        let k = apex[i][j] as usize;
        let x = members[slot] as usize;
        slot += 1;
        tris[x] = [ring[i], ring[k], ring[j]];
        pos[3 * x..3 * x + 3].copy_from_slice(&[at[i], at[k], at[j]]);
        for (a, b) in [(i, k), (k, j)] {
            if let Some(s) = memo[a][b].and_then(|d| d.sample) {
                tested.push((ring[a], ring[b], s));
            }
        }
        stack[top] = (i, k);
        stack[top + 1] = (k, j);
        top += 2;
    }
    debug_assert_eq!(slot, nt);
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::filter::Trilinear;
    use crate::mc::{cell_triangles, Patch};
    use crate::refine::sample;
    use crate::tables::cube::{CORNERS, EDGES};
    use crate::Topology;

    type Filter = Trilinear<'static, f64>;

    fn crossing(f: &[f64; 8], e: u32) -> DVec3 {
        let [a, b] = EDGES[e as usize];
        let t = f[a as usize] / (f[a as usize] - f[b as usize]);
        let (pa, pb) = (CORNERS[a as usize], CORNERS[b as usize]);
        DVec3::from_array(std::array::from_fn(|k| {
            pa[k] as f64 + t * (pb[k] as f64 - pa[k] as f64)
        }))
    }

    /// Directed edges without a reverse, sorted.
    fn outline(tris: &[[u32; 3]]) -> Vec<(u32, u32)> {
        let all: Vec<(u32, u32)> = tris
            .iter()
            .flat_map(|t| (0..3).map(move |e| (t[e], t[(e + 1) % 3])))
            .collect();
        let mut out: Vec<_> = all
            .iter()
            .copied()
            .filter(|&(a, b)| !all.contains(&(b, a)))
            .collect();
        out.sort_unstable();
        out
    }

    /// Interior edges (each once) that refinement cannot bring onto S_K.
    fn stuck(f: &[f64; 8], tris: &[[u32; 3]]) -> usize {
        let mut n = 0;
        for (x, t) in tris.iter().enumerate() {
            for e in 0..3 {
                let (a, b) = (t[e], t[(e + 1) % 3]);
                let twin = tris[x + 1..]
                    .iter()
                    .any(|u| (0..3).any(|g| u[g] == b && u[(g + 1) % 3] == a));
                if twin {
                    let (pa, pb) = (crossing(f, a), crossing(f, b));
                    let (m, reach) = ((pa + pb) * 0.5, (pb - pa).length());
                    n += sample::<Filter>(f, 0.0, m, 0, 1e-3, true, reach).stuck as usize;
                }
            }
        }
        n
    }

    #[test]
    fn recut_polygons_keep_their_outline_and_get_fewer_stuck_diagonals() {
        let mut rng = crate::test_rng::XorShift(0x9e37_79b9_7f4a_7c15);
        let mut next = move || rng.unit();
        let (mut cells, mut recut, mut kept_bits) = (0, 0, 0);
        for n in 0..40_000 {
            // Half the cells hug a face: four corners just off the
            // isovalue, where the surface bends along the face.
            let mut f: [f64; 8] = std::array::from_fn(|_| 2.0 * next() - 1.0);
            if n % 2 == 0 {
                for c in 4..8 {
                    f[c] = 0.05 * (2.0 * next() - 1.0);
                }
            }
            let mut patch = Patch::default();
            cell_triangles(&f, Topology::Trilinear, &mut patch);
            if !patch.extra.is_empty() || patch.tris.len() < 2 {
                continue;
            }
            cells += 1;
            let before: Vec<[u32; 3]> = patch.tris.iter().map(|t| t.map(u32::from)).collect();
            let mut tris = before.clone();
            let mut pos: Vec<DVec3> = tris.iter().flatten().map(|&e| crossing(&f, e)).collect();
            let mut tested = Vec::new();
            let r = choose_diagonals::<Filter>(&f, 0.0, 1e-3, &mut tris, &mut pos, &mut tested);
            // Pure: the same answer twice.
            let mut again = before.clone();
            let mut pos2: Vec<DVec3> = before.iter().flatten().map(|&e| crossing(&f, e)).collect();
            let mut tested2 = Vec::new();
            choose_diagonals::<Filter>(&f, 0.0, 1e-3, &mut again, &mut pos2, &mut tested2);
            assert_eq!(tris, again);
            assert_eq!(tris.len(), before.len());
            assert_eq!(outline(&tris), outline(&before), "cell {f:?}");
            for (t, p) in tris.iter().zip(pos.chunks_exact(3)) {
                for k in 0..3 {
                    assert_eq!(p[k], crossing(&f, t[k]), "positions follow the ids");
                }
            }
            // Every final diagonal was tested once, as the refiner would.
            let diagonals = tris
                .iter()
                .flat_map(|t| (0..3).map(move |e| (t[e], t[(e + 1) % 3])));
            let interior: Vec<_> = diagonals
                .filter(|&(a, b)| a < b && !outline(&tris).contains(&(a, b)))
                .collect();
            let mut got: Vec<(u32, u32)> = tested
                .iter()
                .map(|&(a, b, _)| (a.min(b), a.max(b)))
                .collect();
            got.sort_unstable();
            let mut want: Vec<(u32, u32)> = interior
                .iter()
                .copied()
                .filter(|&(a, b)| shared_fixed_axes(crossing(&f, a), crossing(&f, b)) == 0)
                .collect();
            want.sort_unstable();
            assert_eq!(got, want, "the final diagonals' tests, each once");
            for &(a, b, s) in &tested {
                let (pa, pb) = (crossing(&f, a), crossing(&f, b));
                let fresh = sample_edge::<Filter>(&f, 0.0, pa, pb, 0, 1e-3, true);
                assert_eq!((s.split, s.stuck), (fresh.split, fresh.stuck));
            }
            if r == 0 {
                assert_eq!(tris, before, "unchanged unless re-cut");
                kept_bits += 1;
                continue;
            }
            recut += 1;
            assert!(stuck(&f, &tris) < stuck(&f, &before), "cell {f:?}");
            for t in &tris {
                for e in 0..3 {
                    let (a, b) = (crossing(&f, t[e]), crossing(&f, t[(e + 1) % 3]));
                    let inner = !outline(&tris).contains(&(t[e], t[(e + 1) % 3]));
                    assert!(
                        !inner || shared_fixed_axes(a, b) == 0,
                        "a diagonal flat in a face"
                    );
                }
            }
        }
        eprintln!("{cells} cells, {recut} re-cut");
        assert!(
            cells > 10_000 && recut > 100,
            "{cells} cells, {recut} re-cut"
        );
        assert!(kept_bits > recut);
    }
}
