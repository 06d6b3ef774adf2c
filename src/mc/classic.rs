//! The fixed case table of `vtkMarchingCubes`.

use crate::tables::VTK_TRIANGLE_CASES;

/// Appends the table's triangles for `case`.
#[inline]
pub fn triangles(case: u8, out: &mut Vec<[u8; 3]>) {
    let row = &VTK_TRIANGLE_CASES[case as usize];
    let mut t = 0;
    while t + 2 < 16 && row[t] >= 0 {
        out.push([row[t] as u8, row[t + 1] as u8, row[t + 2] as u8]);
        t += 3;
    }
}
