//! Corner, edge and face numbering of a cell, as in VTK's `vtkMarchingCubes`.
//!
//! ```text
//!         7 ________ 6           edges (corner pairs, lower index first
//!         /|       /|            along the axis, so every edge points in
//!        / |      / |            the positive axis direction):
//!      4/__|_____/5 |             0: 0-1   4: 4-5   8: 0-4
//!       |  |_____|__|             1: 1-2   5: 5-6   9: 1-5
//!       | 3/     |  /2            2: 3-2   6: 7-6  10: 3-7
//!       | /      | /              3: 0-3   7: 4-7  11: 2-6
//!       |/_______|/
//!       0        1        x to the right, y into the page, z up
//! ```
//! Corner `i` sits at [`CORNERS`]`[i]` in the cell's local coordinates
//! (each in {0, 1}). The case index of a cell has bit `i` set when corner
//! `i` is at or above the isovalue ("inside").

/// Local coordinates (x, y, z) of the eight corners.
pub const CORNERS: [[u8; 3]; 8] = [
    [0, 0, 0],
    [1, 0, 0],
    [1, 1, 0],
    [0, 1, 0],
    [0, 0, 1],
    [1, 0, 1],
    [1, 1, 1],
    [0, 1, 1],
];

/// The twelve edges as (lower corner, upper corner).
pub const EDGES: [[u8; 2]; 12] = [
    [0, 1],
    [1, 2],
    [3, 2],
    [0, 3],
    [4, 5],
    [5, 6],
    [7, 6],
    [4, 7],
    [0, 4],
    [1, 5],
    [3, 7],
    [2, 6],
];

/// Axis (0 = x, 1 = y, 2 = z) along which each edge runs.
pub const EDGE_AXIS: [u8; 12] = [0, 1, 0, 1, 0, 1, 0, 1, 2, 2, 2, 2];

/// The six faces: (fixed axis, fixed local coordinate, corners in cyclic
/// order). Opposite corners of a face are entries 0/2 and 1/3.
pub const FACES: [(u8, u8, [u8; 4]); 6] = [
    (0, 0, [0, 3, 7, 4]),
    (0, 1, [1, 2, 6, 5]),
    (1, 0, [0, 1, 5, 4]),
    (1, 1, [3, 2, 6, 7]),
    (2, 0, [0, 1, 2, 3]),
    (2, 1, [4, 5, 6, 7]),
];

/// The edge joining two corners, if they share one.
pub const fn edge_between(a: u8, b: u8) -> Option<u8> {
    let mut e = 0;
    while e < 12 {
        let [p, q] = EDGES[e];
        if (p == a && q == b) || (p == b && q == a) {
            return Some(e as u8);
        }
        e += 1;
    }
    None
}

/// The four edges of each face, in the cyclic order of its corners
/// (edge `k` joins face corners `k` and `k + 1`).
pub const FACE_EDGES: [[u8; 4]; 6] = {
    let mut out = [[0u8; 4]; 6];
    let mut f = 0;
    while f < 6 {
        let c = FACES[f].2;
        let mut k = 0;
        while k < 4 {
            out[f][k] = match edge_between(c[k], c[(k + 1) % 4]) {
                Some(e) => e,
                None => panic!("face corners must be adjacent"),
            };
            k += 1;
        }
        f += 1;
    }
    out
};

/// The faces each vertex id of a patch lies on, bit `f` for `FACES[f]`:
/// ids 0..12 are cell edges (two faces each), ids 12..16 interior points
/// of the cell (none). A triangle of a patch can lie flat in a face only
/// if the masks of its three ids share a bit (or a point sits on a grid
/// point).
pub const VERTEX_FACES: [u8; 16] = {
    let mut out = [0u8; 16];
    let mut f = 0;
    while f < 6 {
        let mut k = 0;
        while k < 4 {
            out[FACE_EDGES[f][k] as usize] |= 1 << f;
            k += 1;
        }
        f += 1;
    }
    out
};

/// Whether three vertex ids of a patch (see [`VERTEX_FACES`]) all lie on
/// one cell face, so that a triangle on them may lie flat in it.
#[inline]
pub const fn on_one_face(ids: [u8; 3]) -> bool {
    VERTEX_FACES[ids[0] as usize] & VERTEX_FACES[ids[1] as usize] & VERTEX_FACES[ids[2] as usize]
        != 0
}

/// Whether the sign pattern `case` makes face `f` ambiguous (diagonally
/// opposite corners agree and adjacent corners differ).
#[inline]
pub const fn face_is_ambiguous(case: u8, f: usize) -> bool {
    let c = FACES[f].2;
    let s0 = (case >> c[0]) & 1;
    let s1 = (case >> c[1]) & 1;
    let s2 = (case >> c[2]) & 1;
    let s3 = (case >> c[3]) & 1;
    s0 == s2 && s1 == s3 && s0 != s1
}

/// The ambiguous faces of each sign pattern, bit `k` for face `k`
/// ([`face_is_ambiguous`]): the asymptotic decider visits only these.
pub const AMBIGUOUS_FACES: [u8; 256] = {
    let mut out = [0u8; 256];
    let mut c = 0;
    while c < 256 {
        let mut f = 0;
        while f < 6 {
            if face_is_ambiguous(c as u8, f) {
                out[c] |= 1 << f;
            }
            f += 1;
        }
        c += 1;
    }
    out
};

/// Cases whose trilinear topology may differ from the fixed table: an
/// ambiguous face, or two lone corners on a body diagonal (MC case 4 and
/// its complement, whose interior may hold a tunnel).
pub const NEEDS_TOPOLOGY_TEST: [bool; 256] = {
    let mut out = [false; 256];
    let mut c = 0;
    while c < 256 {
        let case = c as u8;
        let mut amb = AMBIGUOUS_FACES[c] != 0;
        let pos = case.count_ones();
        let diag = [(0u8, 6u8), (1, 7), (2, 4), (3, 5)];
        let mut d = 0;
        while d < 4 {
            let m = (1u8 << diag[d].0) | (1u8 << diag[d].1);
            if (pos == 2 && case == m) || (pos == 6 && case == !m) {
                amb = true;
            }
            d += 1;
        }
        out[c] = amb;
        c += 1;
    }
    out
};

/// The edges the surface crosses in each case (their corners lie on
/// either side), in increasing order, and how many. Every topology puts
/// exactly one point on each of them, so the extraction places a cell's
/// edge points from this list, each edge once, before its triangles.
pub const CROSSED_EDGES: [([u8; 12], u8); 256] = {
    let mut out = [([0u8; 12], 0u8); 256];
    let mut c = 0;
    while c < 256 {
        let mut n = 0;
        let mut e = 0;
        while e < 12 {
            let [a, b] = EDGES[e];
            if ((c >> a) & 1) != ((c >> b) & 1) {
                out[c].0[n] = e as u8;
                n += 1;
            }
            e += 1;
        }
        out[c].1 = n as u8;
        c += 1;
    }
    out
};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edges_point_along_positive_axes() {
        for (e, [a, b]) in EDGES.iter().enumerate() {
            let pa = CORNERS[*a as usize];
            let pb = CORNERS[*b as usize];
            let ax = EDGE_AXIS[e] as usize;
            for k in 0..3 {
                if k == ax {
                    assert_eq!(pa[k] + 1, pb[k]);
                } else {
                    assert_eq!(pa[k], pb[k]);
                }
            }
        }
    }

    #[test]
    fn faces_are_planar_and_cyclic() {
        for (f, (axis, val, corners)) in FACES.iter().enumerate() {
            for c in corners {
                assert_eq!(CORNERS[*c as usize][*axis as usize], *val);
            }
            for e in FACE_EDGES[f] {
                let [a, b] = EDGES[e as usize];
                assert!(corners.contains(&a) && corners.contains(&b));
            }
        }
    }

    #[test]
    fn each_edge_lies_on_the_two_faces_of_its_coordinates() {
        // Edge e lies on face (axis, val) iff both its corners have
        // coordinate val on that axis.
        for (e, [a, b]) in EDGES.iter().enumerate() {
            let (pa, pb) = (CORNERS[*a as usize], CORNERS[*b as usize]);
            let mut expected = 0u8;
            for (f, (axis, val, _)) in FACES.iter().enumerate() {
                let k = *axis as usize;
                if pa[k] == *val && pb[k] == *val {
                    expected |= 1 << f;
                }
            }
            assert_eq!(VERTEX_FACES[e], expected, "edge {e}");
            assert_eq!(expected.count_ones(), 2);
        }
        assert!(VERTEX_FACES[12..].iter().all(|&m| m == 0));
    }

    #[test]
    fn ambiguity_counts_match_mc_literature() {
        // 6 faces, 2 ambiguous sign patterns of 16 each: every face is
        // ambiguous in 2 * 16 = 32 of the 256 cases.
        for f in 0..6 {
            let n = (0..=255u8).filter(|&c| face_is_ambiguous(c, f)).count();
            assert_eq!(n, 32);
            let masked = (0..=255usize)
                .filter(|&c| AMBIGUOUS_FACES[c] >> f & 1 == 1)
                .count();
            assert_eq!(masked, 32);
        }
        assert!((0..=255u8).all(|c| (0..6)
            .all(|f| face_is_ambiguous(c, f) == (AMBIGUOUS_FACES[c as usize] >> f & 1 == 1))));
        assert!(NEEDS_TOPOLOGY_TEST[0b0100_0001]); // corners 0 and 6
        assert!(!NEEDS_TOPOLOGY_TEST[1]);
    }

    #[test]
    fn crossed_edges_are_those_with_one_corner_inside() {
        for c in 0..=255u8 {
            let (list, n) = CROSSED_EDGES[c as usize];
            let list = &list[..n as usize];
            assert!(list.windows(2).all(|w| w[0] < w[1]), "case {c}");
            for (e, [a, b]) in EDGES.iter().enumerate() {
                let crossed = (c >> a) & 1 != (c >> b) & 1;
                assert_eq!(list.contains(&(e as u8)), crossed, "case {c} edge {e}");
            }
        }
        assert_eq!(CROSSED_EDGES[0].1, 0);
        assert_eq!(&CROSSED_EDGES[1].0[..3], &[0, 3, 8]);
    }
}
