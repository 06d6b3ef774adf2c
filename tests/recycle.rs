//! `Mesh::recycle`: a mesh's arrays go back to the library's bins, the next
//! extraction reuses them, and the output does not change. (A file of its
//! own: the bins are process-wide, and tests of one binary run at once.)

use precisemc::{extract, release_retained_memory, retained_bytes, samples, Options};

#[test]
fn recycled_arrays_are_kept_reused_and_change_nothing() {
    let s = samples::atoms(24);
    let v = s.volume();
    let o = Options {
        epsilon: 0.01,
        threads: 2,
        ..Options::default()
    };
    release_retained_memory();
    let first = extract(&v, s.isovalue, &o).unwrap();
    assert!(first.triangles.len() > 1000);
    let (tris, points, levels) = (
        first.triangles.clone(),
        first.points.clone(),
        first.levels.clone(),
    );
    let before = retained_bytes();
    let tri_bytes = std::mem::size_of::<[u64; 3]>() * first.triangles.capacity();
    let mut held = first.triangles.as_ptr() as usize;
    first.recycle();
    assert!(
        retained_bytes() >= before + tri_bytes,
        "the triangles' {tri_bytes} bytes are kept ({before} -> {})",
        retained_bytes()
    );
    for _ in 0..3 {
        let again = extract(&v, s.isovalue, &o).unwrap();
        // Reused: the output is written into the array recycled before.
        assert_eq!(
            again.triangles.as_ptr() as usize,
            held,
            "the recycled triangle array was not reused"
        );
        held = again.triangles.as_ptr() as usize;
        assert_eq!(again.triangles, tris);
        assert_eq!(again.levels, levels);
        assert!(again
            .points
            .iter()
            .zip(&points)
            .all(|(a, b)| a.map(f64::to_bits) == b.map(f64::to_bits)));
        again.recycle();
    }
    assert!(release_retained_memory() >= tri_bytes);
    assert_eq!(retained_bytes(), 0);
    assert_eq!(release_retained_memory(), 0);
}
