//! `Mesh::recycle`: a mesh's arrays go back to the library's bins, the next
//! extraction reuses them, and the output does not change. (A file of its
//! own: the bins are process-wide, and tests of one binary run at once;
//! the tests here take turns through `ONE_AT_A_TIME`.)

use std::sync::Mutex;

use precisemc::{extract, release_retained_memory, retained_bytes, samples, Options};

/// Held by each test for its whole run: another one's
/// `release_retained_memory` would empty the bins under it.
static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

#[test]
fn recycled_arrays_are_kept_reused_and_change_nothing() {
    let _turn = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
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
    first.recycle();
    assert!(
        retained_bytes() >= before + tri_bytes,
        "the triangles' {tri_bytes} bytes are kept ({before} -> {})",
        retained_bytes()
    );
    // Recycled again and again on two threads, the output does not change.
    for _ in 0..3 {
        let again = extract(&v, s.isovalue, &o).unwrap();
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

    // Reused: what an extraction leaves in the bins is the same whether the
    // mesh recycled before it gave back its triangle array or not (taken
    // from the bin, or made afresh). Counted in bytes, on one thread (the
    // slabs' scratch then goes the same way in both runs): pointers cannot
    // tell, as the allocator may hand a freed block out again.
    let one = Options { threads: 1, ..o };
    let left_after = |keep_triangles: bool| {
        release_retained_memory();
        let mut m = extract(&v, s.isovalue, &one).unwrap();
        let bytes = std::mem::size_of::<[u64; 3]>() * m.triangles.capacity();
        if !keep_triangles {
            m.triangles = Vec::new();
        }
        m.recycle();
        let kept = retained_bytes();
        let again = extract(&v, s.isovalue, &one).unwrap();
        assert_eq!(again.triangles, tris);
        (kept, retained_bytes(), bytes)
    };
    let (kept_with, left_with, bytes) = left_after(true);
    let (kept_without, left_without, _) = left_after(false);
    assert!(bytes >= std::mem::size_of::<[u64; 3]>() * tris.len());
    assert_eq!(
        kept_with - kept_without,
        bytes,
        "the triangle array is kept"
    );
    assert_eq!(left_with, left_without, "the kept triangle array is reused");
    release_retained_memory();
}

#[test]
fn recycled_normals_and_gradients_are_kept_reused_and_change_nothing() {
    let _turn = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let s = samples::atoms(20);
    let v = s.volume();
    // One thread: with more, how many scratch sets the slabs take and
    // which kept buffer each slab gets depend on scheduling, and the byte
    // counts compared below with them.
    let with = Options {
        epsilon: 0.01,
        normals: precisemc::NormalMode::Gradient,
        gradients: true,
        threads: 1,
        ..Options::default()
    };
    let without = Options {
        normals: precisemc::NormalMode::None,
        gradients: false,
        ..with.clone()
    };
    // Bytes retained once a mesh is recycled (from empty bins), with its
    // normals and gradients or with them dropped first. (Pointers cannot
    // tell: the allocator may hand a freed block out again.)
    let recycled = |keep_vectors: bool| {
        release_retained_memory();
        let mut m = extract(&v, s.isovalue, &with).unwrap();
        let bytes = 12 * (m.normals.capacity() + m.gradients.capacity());
        if !keep_vectors {
            m.normals = Vec::new();
            m.gradients = Vec::new();
        }
        m.recycle();
        (retained_bytes(), bytes)
    };
    let (kept, vector_bytes) = recycled(true);
    let (dropped, _) = recycled(false);
    assert!(vector_bytes > 12 * 1000);
    assert_eq!(
        kept as i64 - dropped as i64,
        vector_bytes as i64,
        "normals and gradients kept"
    );
    // The next extraction takes them from the bins: with normals and
    // gradients it leaves their bytes fewer behind than without.
    let left_after = |o: &Options| {
        recycled(true);
        let m = extract(&v, s.isovalue, o).unwrap();
        let left = retained_bytes();
        (left, m)
    };
    let (left_with, a) = left_after(&with);
    let (left_without, _) = left_after(&without);
    assert_eq!(
        left_without as i64 - left_with as i64,
        vector_bytes as i64,
        "normals and gradients reused"
    );
    release_retained_memory();
    let fresh = extract(&v, s.isovalue, &with).unwrap();
    assert_eq!(a.normals, fresh.normals);
    assert_eq!(a.gradients, fresh.gradients);
    assert!(!fresh.normals.is_empty());
}
