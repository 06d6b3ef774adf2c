//! Whether the fixed table's patch of a cell has the topology of the
//! trilinear interpolant's isosurface there.
//!
//! Refinement moves split points onto `S_K`, the trilinear surface. With
//! the Classic topology a cell's table patch can join the crossings
//! differently from `S_K` (an ambiguous face cut the other way, two caps
//! where `S_K` has a tunnel): its samples then keep failing to reach `S_K`
//! or reach it across the cell, and refinement never converges (one ±1
//! checkerboard cell refined to level 9 with rule B gave 3 M triangles).
//! The extraction refines such cells on their faces' edges only.

use super::classic;
use super::trilinear::{self, UnionFind};
use crate::tables::cube::NEEDS_TOPOLOGY_TEST;

/// Whether the table's triangles for `case` (`== case_index(f)`) have the
/// topology of the trilinear interpolant's isosurface in the cell: the
/// same boundary segments on the faces and the same crossings joined into
/// one piece. Always true for a case the table cannot get wrong
/// (no ambiguous face, no lone corners on a body diagonal) and for a cell
/// with a NaN or infinite corner (nothing to compare with). `extra` and
/// `tris` are scratch.
pub fn classic_is_trilinear(
    case: u8,
    f: &[f64; 8],
    tris: &mut Vec<[u8; 3]>,
    extra: &mut Vec<[f64; 3]>,
) -> bool {
    if !NEEDS_TOPOLOGY_TEST[case as usize] || !f.iter().all(|v| v.is_finite()) {
        return true;
    }
    tris.clear();
    extra.clear();
    trilinear::triangles(f, false, tris, extra);
    Shape::of(classic::case_triangles(case)) == Shape::of(tris)
}

/// What a patch's topology is compared by: its boundary segments (pairs of
/// crossed cell edges joined by exactly one triangle side) and which
/// crossed edges lie in one connected piece (an interior point, id 12 and
/// up, only links the pieces it touches).
#[derive(PartialEq, Eq)]
struct Shape {
    /// Bit `b` of `boundary[a]` (`a < b < 12`): the segment `a b` bounds.
    boundary: [u16; 12],
    /// Bit `b` of `piece[a]`: crossed edges `a` and `b` are in one piece.
    piece: [u16; 12],
}

impl Shape {
    fn of(tris: &[[u8; 3]]) -> Self {
        // Interior points are few (ids below 32 cover every patch).
        let mut uf = UnionFind::<32>::new();
        let mut sides = [0u8; 12 * 12];
        let mut used = 0u32;
        for t in tris {
            for e in 0..3 {
                let (a, b) = (t[e].min(t[(e + 1) % 3]), t[e].max(t[(e + 1) % 3]));
                used |= 1 << a.min(31) | 1 << b.min(31);
                if b < 12 {
                    sides[12 * a as usize + b as usize] += 1;
                }
                uf.union(a.min(31), b.min(31));
            }
        }
        let mut shape = Shape {
            boundary: [0; 12],
            piece: [0; 12],
        };
        for a in 0..12u8 {
            for b in (a + 1)..12u8 {
                if sides[12 * a as usize + b as usize] == 1 {
                    shape.boundary[a as usize] |= 1 << b;
                }
                if used & (1 << a) != 0 && used & (1 << b) != 0 && uf.find(a) == uf.find(b) {
                    shape.piece[a as usize] |= 1 << b;
                }
            }
        }
        shape
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mc::case_index;
    use crate::test_rng::XorShift;

    #[test]
    fn unambiguous_cases_agree_whatever_the_triangulation() {
        // The table and the trilinear code triangulate the same disks
        // differently (fans, interior points): only the topology counts.
        let mut rng = XorShift(7);
        let (mut tris, mut extra) = (Vec::new(), Vec::new());
        let mut checked = 0;
        for _ in 0..20_000 {
            let f: [f64; 8] = std::array::from_fn(|_| rng.unit() * 2.0 - 1.0);
            let case = case_index(&f);
            if !NEEDS_TOPOLOGY_TEST[case as usize] && case != 0 && case != 255 {
                tris.clear();
                extra.clear();
                trilinear::triangles(&f, true, &mut tris, &mut extra);
                assert!(
                    Shape::of(classic::case_triangles(case)) == Shape::of(&tris),
                    "{f:?}"
                );
                checked += 1;
            }
        }
        assert!(checked > 5_000);
    }

    #[test]
    fn the_table_disagrees_where_the_interpolant_joins_corners_otherwise() {
        let (mut tris, mut extra) = (Vec::new(), Vec::new());
        // ±1 checkerboard cell: corners of value 1 are 0, 2, 5, 7 (VTK
        // order: x fastest along 0-1, 3-2, 4-5, 7-6).
        let checker = [1.0, -1.0, 1.0, -1.0, -1.0, 1.0, -1.0, 1.0];
        // Isovalue -0.5: every face saddle (0) lies above it, so the
        // interpolant joins the corners of value 1 across every face (a
        // connected inside); the table cuts off four separate corners.
        let f = checker.map(|v: f64| v + 0.5);
        let case = case_index(&f);
        assert!(!classic_is_trilinear(case, &f, &mut tris, &mut extra));
        // Two lone corners on a body diagonal: the interpolant joins them
        // by a tunnel (six triangles) when the other corners lie just below
        // the isovalue (its body saddle is then above it); the table has
        // two caps. Far below, both have the two caps.
        for (a, same) in [
            (0.01, false),
            (0.1, false),
            (0.3, false),
            (0.5, true),
            (1.0, true),
        ] {
            let mut f = [-a; 8];
            f[0] = 1.0;
            f[6] = 1.0;
            assert_eq!(
                classic_is_trilinear(case_index(&f), &f, &mut tris, &mut extra),
                same,
                "{a}"
            );
        }
    }
}
