//! The fixed case table of `vtkMarchingCubes`.

use crate::tables::cube::on_one_face;
use crate::tables::VTK_TRIANGLE_CASES;

/// The table regrouped for copying: each case's triangles as edge triples,
/// and how many there are (the `-1` terminator found once, at compile
/// time, rather than for every cell).
const TRIANGLES: [([[u8; 3]; 5], u8); 256] = {
    let mut out = [([[0u8; 3]; 5], 0u8); 256];
    let mut c = 0;
    while c < 256 {
        let row = &VTK_TRIANGLE_CASES[c];
        let mut t = 0;
        while t < 5 && row[3 * t] >= 0 {
            out[c].0[t] = [row[3 * t] as u8, row[3 * t + 1] as u8, row[3 * t + 2] as u8];
            t += 1;
        }
        out[c].1 = t as u8;
        c += 1;
    }
    out
};

/// Appends the table's triangles for `case`.
#[inline]
pub fn triangles(case: u8, out: &mut Vec<[u8; 3]>) {
    out.extend_from_slice(case_triangles(case));
}

/// The table's triangles for `case`, borrowed (no copy into a patch).
#[inline]
pub fn case_triangles(case: u8) -> &'static [[u8; 3]] {
    let (tris, n) = &TRIANGLES[case as usize];
    &tris[..*n as usize]
}

/// Whether any of the table's triangles for a case has its three points
/// on edges of one cell face (see [`crate::tables::cube::on_one_face`]).
pub const HAS_FACE_TRIANGLE: [bool; 256] = {
    let mut out = [false; 256];
    let mut c = 0;
    while c < 256 {
        let (tris, n) = &TRIANGLES[c];
        let mut t = 0;
        while t < *n as usize {
            if on_one_face(tris[t]) {
                out[c] = true;
            }
            t += 1;
        }
        c += 1;
    }
    out
};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regrouped_table_lists_the_same_triangles() {
        for case in 0..=255u8 {
            let mut got = Vec::new();
            triangles(case, &mut got);
            let row = &VTK_TRIANGLE_CASES[case as usize];
            let n = row.iter().position(|&e| e < 0).unwrap_or(16) / 3;
            assert_eq!(got.len(), n, "case {case}");
            for (t, tri) in got.iter().enumerate() {
                let want = [row[3 * t], row[3 * t + 1], row[3 * t + 2]].map(|e| e as u8);
                assert_eq!(*tri, want, "case {case}");
            }
            let flat = got.iter().any(|&t| on_one_face(t));
            assert_eq!(HAS_FACE_TRIANGLE[case as usize], flat, "case {case}");
        }
    }
}
