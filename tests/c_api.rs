//! The C API called directly from Rust: its results equal the Rust API's
//! bit for bit, its layout is the one the C tests pin, and its error state
//! is per thread.

use std::ffi::{c_int, c_void, CStr};
use std::mem::size_of;
use std::ops::ControlFlow;
use std::ptr;

use precisemc::ffi::*;
use precisemc::{
    extract, extract_with_progress, Mesh, NormalMode, Options, Rule, Topology, Volume,
};

fn sphere(n: u64, c: [f64; 3]) -> Vec<f32> {
    let mut d = Vec::new();
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let (x, y, z) = (i as f64 - c[0], j as f64 - c[1], k as f64 - c[2]);
                // Two blobs: some ambiguous cells and refinement.
                let a = (x * x + y * y + z * z).sqrt();
                let b = ((x - 4.0).powi(2) + (y + 1.0).powi(2) + (z - 2.0).powi(2)).sqrt();
                d.push(a.min(b + 0.7) as f32);
            }
        }
    }
    d
}

fn c_volume(data: &[f32], dims: [u64; 3]) -> pmc_volume {
    pmc_volume {
        struct_size: std::mem::size_of::<pmc_volume>() as u64,
        data: data.as_ptr().cast(),
        len: data.len() as u64,
        scalar_type: PmcScalarType::F32 as pmc_scalar_type,
        dims,
        strides: [0; 3],
        origin: [0.5, -1.0, 2.0],
        spacing: [0.5, 1.0, 1.25],
    }
}

/// Owns a C mesh handle.
struct CMesh(*mut pmc_mesh);

impl Drop for CMesh {
    fn drop(&mut self) {
        unsafe { pmc_mesh_free(self.0) }
    }
}

impl CMesh {
    fn slice<T>(&self, p: *const T, len: u64) -> &[T] {
        if len == 0 {
            assert!(p.is_null());
            &[]
        } else {
            assert!(!p.is_null());
            unsafe { std::slice::from_raw_parts(p, len as usize) }
        }
    }

    /// Asserts that this mesh equals `m` exactly (times excepted).
    fn assert_equals(&self, m: &Mesh) {
        let h = self.0;
        let (np, nt) = unsafe { (pmc_mesh_point_count(h), pmc_mesh_triangle_count(h)) };
        assert_eq!(np, m.points.len() as u64);
        assert_eq!(nt, m.triangles.len() as u64);
        let flat = |v: &[[f64; 3]]| v.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(
            bits(self.slice(unsafe { pmc_mesh_points(h) }, 3 * np)),
            flat(&m.points)
        );
        assert_eq!(
            bits(self.slice(unsafe { pmc_mesh_index_points(h) }, 3 * np)),
            flat(&m.index_points)
        );
        let tris: Vec<i64> = m.triangles.iter().flatten().map(|&i| i as i64).collect();
        assert_eq!(
            self.slice(unsafe { pmc_mesh_triangles(h) }, 3 * nt),
            &tris[..]
        );
        assert_eq!(
            self.slice(unsafe { pmc_mesh_triangle_levels(h) }, nt),
            &m.levels[..]
        );
        let normals: Vec<f32> = m.normals.iter().flatten().copied().collect();
        let cn = unsafe { pmc_mesh_normals(h) };
        if normals.is_empty() {
            assert!(cn.is_null());
        } else {
            assert_eq!(self.slice(cn, 3 * np), &normals[..]);
        }
        let bits32 = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let gradients: Vec<f32> = m.gradients.iter().flatten().copied().collect();
        let cg = unsafe { pmc_mesh_gradients(h) };
        if gradients.is_empty() {
            assert!(cg.is_null());
        } else {
            assert_eq!(bits32(self.slice(cg, 3 * np)), bits32(&gradients));
        }
        let mut s = pmc_stats::default();
        assert_eq!(unsafe { pmc_mesh_stats(h, &mut s) }, PmcStatus::Ok);
        let r = &m.stats;
        assert_eq!(
            (
                s.cells,
                s.mc_triangles,
                s.output_triangles,
                s.output_points,
                s.ambiguous_cells
            ),
            (
                r.cells,
                r.mc_triangles,
                r.output_triangles,
                r.output_points,
                r.ambiguous_cells
            )
        );
        assert_eq!(
            (
                s.skipped_nonfinite_cells,
                s.samples_evaluated,
                s.split_points
            ),
            (
                r.skipped_nonfinite_cells,
                r.samples_evaluated,
                r.split_points
            )
        );
        assert_eq!(
            (
                s.projection_failures,
                s.faces_above_epsilon,
                s.max_level,
                s.effective_max_level
            ),
            (
                r.projection_failures,
                r.faces_above_epsilon,
                r.max_level,
                r.effective_max_level
            )
        );
        assert_eq!(s.mean_level.to_bits(), r.mean_level.to_bits());
        assert_eq!(s.budget_reached != 0, r.budget_reached);
    }
}

fn c_extract(v: &pmc_volume, iso: f64, o: *const pmc_options) -> Result<CMesh, PmcStatus> {
    let mut m = ptr::null_mut();
    match unsafe { pmc_extract(v, iso, o, &mut m) } {
        PmcStatus::Ok => {
            assert!(!m.is_null());
            Ok(CMesh(m))
        }
        s => {
            assert!(m.is_null());
            Err(s)
        }
    }
}

fn last_error() -> String {
    let n = unsafe { pmc_last_error_message(ptr::null_mut(), 0) };
    let mut buf = vec![0u8; n + 1];
    assert_eq!(
        unsafe { pmc_last_error_message(buf.as_mut_ptr().cast(), buf.len()) },
        n
    );
    CStr::from_bytes_with_nul(&buf)
        .unwrap()
        .to_str()
        .unwrap()
        .to_owned()
}

#[test]
fn layout_matches_the_c_tests() {
    use std::mem::offset_of;
    // The version 1 layouts (struct_size first). Sizes the library
    // accepts are pinned by `struct_size_is_checked_and_respected`.
    assert_eq!(size_of::<pmc_volume>(), 128);
    assert_eq!(offset_of!(pmc_volume, struct_size), 0);
    assert_eq!(offset_of!(pmc_volume, data), 8);
    assert_eq!(offset_of!(pmc_volume, len), 16);
    assert_eq!(offset_of!(pmc_volume, scalar_type), 24);
    assert_eq!(offset_of!(pmc_volume, dims), 32);
    assert_eq!(offset_of!(pmc_volume, strides), 56);
    assert_eq!(offset_of!(pmc_volume, origin), 80);
    assert_eq!(offset_of!(pmc_volume, spacing), 104);
    assert_eq!(size_of::<pmc_stats>(), 152);
    assert_eq!(offset_of!(pmc_stats, struct_size), 0);
    assert_eq!(offset_of!(pmc_stats, cells), 8);
    assert_eq!(offset_of!(pmc_stats, max_level), 88);
    assert_eq!(offset_of!(pmc_stats, mean_level), 96);
    assert_eq!(offset_of!(pmc_stats, budget_reached), 104);
    assert_eq!(offset_of!(pmc_stats, time_total), 144);
    assert_eq!(size_of::<pmc_distance>(), 48);
    assert_eq!(offset_of!(pmc_distance, struct_size), 0);
    assert_eq!(offset_of!(pmc_distance, max), 8);
    assert_eq!(offset_of!(pmc_distance, unresolved), 40);
    assert_eq!(size_of::<PmcStatus>(), 4);
    assert_eq!(PMC_MAX_LEVEL_LIMIT, precisemc::MAX_LEVEL_LIMIT);
}

#[test]
fn enum_values_are_stable() {
    let s = [
        PmcStatus::Ok,
        PmcStatus::NullArgument,
        PmcStatus::InvalidArgument,
        PmcStatus::Aborted,
        PmcStatus::OutOfMemory,
        PmcStatus::InternalError,
    ];
    for (i, v) in s.iter().enumerate() {
        assert_eq!(*v as u32, i as u32);
        assert_eq!(PmcStatus::from_raw(i as u32), Some(*v));
    }
    assert_eq!(PmcStatus::from_raw(6), None);
    assert_eq!(PmcScalarType::ALL.len(), 10);
    for (i, v) in PmcScalarType::ALL.iter().enumerate() {
        assert_eq!(*v as u32, i as u32);
    }
    assert_eq!(PmcScalarType::from_raw(10), None);
    assert_eq!(PmcTopology::from_raw(2), None);
    assert_eq!(PmcRule::from_raw(4), None);
    assert_eq!(PmcNormals::from_raw(3), None);
    assert_eq!(PmcRule::from_raw(u32::MAX), None);
    assert_eq!(PmcNormals::CentralDifference as u32, 2);
}

#[test]
fn c_api_equals_rust_api() {
    let n = 20;
    let data = sphere(n, [8.3, 9.1, 8.7]);
    let cv = c_volume(&data, [n, n, n]);
    let rv = Volume::new(&data, [n, n, n])
        .with_origin(cv.origin)
        .with_spacing(cv.spacing);
    let cases: Vec<(PmcRule, PmcTopology, PmcNormals, f64, u32, u64)> = vec![
        (
            PmcRule::A1,
            PmcTopology::Trilinear,
            PmcNormals::None,
            0.01,
            5,
            0,
        ),
        (
            PmcRule::A,
            PmcTopology::Classic,
            PmcNormals::Gradient,
            0.02,
            3,
            0,
        ),
        (
            PmcRule::A2,
            PmcTopology::Trilinear,
            PmcNormals::CentralDifference,
            0.005,
            4,
            0,
        ),
        (
            PmcRule::B,
            PmcTopology::Classic,
            PmcNormals::None,
            0.0,
            5,
            0,
        ),
        (
            PmcRule::B,
            PmcTopology::Trilinear,
            PmcNormals::Gradient,
            0.001,
            6,
            5000,
        ),
    ];
    // Gradients in every other case: with and without normals of each mode.
    for (case, (rule, topo, normals, eps, level, cap)) in cases.into_iter().enumerate() {
        let gradients = case % 2 == 1;
        let o = pmc_options_new();
        unsafe {
            assert_eq!(
                pmc_options_set_gradients(o, gradients as c_int),
                PmcStatus::Ok
            );
            assert_eq!(pmc_options_set_rule(o, rule as u32), PmcStatus::Ok);
            assert_eq!(pmc_options_set_topology(o, topo as u32), PmcStatus::Ok);
            assert_eq!(pmc_options_set_normals(o, normals as u32), PmcStatus::Ok);
            assert_eq!(pmc_options_set_epsilon(o, eps), PmcStatus::Ok);
            assert_eq!(pmc_options_set_max_level(o, level), PmcStatus::Ok);
            assert_eq!(pmc_options_set_max_triangles(o, cap), PmcStatus::Ok);
            assert_eq!(pmc_options_set_threads(o, 2), PmcStatus::Ok);
        }
        let ro = Options {
            epsilon: eps,
            max_level: level,
            rule: match rule {
                PmcRule::A => Rule::A,
                PmcRule::A1 => Rule::A1,
                PmcRule::A2 => Rule::A2,
                PmcRule::B => Rule::B,
            },
            topology: match topo {
                PmcTopology::Trilinear => Topology::Trilinear,
                PmcTopology::Classic => Topology::Classic,
            },
            normals: match normals {
                PmcNormals::None => NormalMode::None,
                PmcNormals::Gradient => NormalMode::Gradient,
                PmcNormals::CentralDifference => NormalMode::CentralDifference,
            },
            gradients,
            max_triangles: cap,
            threads: 1,
            reconstruction: precisemc::Reconstruction::Trilinear,
        };
        let cm = c_extract(&cv, 5.5, o).unwrap();
        let rm = extract(&rv, 5.5, &ro).unwrap();
        assert!(!rm.triangles.is_empty());
        assert_eq!(
            rm.gradients.len(),
            if gradients { rm.points.len() } else { 0 }
        );
        cm.assert_equals(&rm);
        unsafe { pmc_options_free(o) };
    }
    // NULL options are the defaults.
    let cm = c_extract(&cv, 5.5, ptr::null()).unwrap();
    cm.assert_equals(&extract(&rv, 5.5, &Options::default()).unwrap());
}

#[test]
fn triangles_move_out_and_world_points_come_on_request() {
    let n = 24;
    let data = sphere(n, [11.3, 10.1, 12.7]);
    let mut cv = c_volume(&data, [n, n, n]);
    cv.origin = [-3.25, 0.5, 7.0];
    cv.spacing = [0.3, 1.7, 0.9];
    let rv = Volume::new(&data, [n, n, n])
        .with_origin(cv.origin)
        .with_spacing(cv.spacing);
    for eps in [0.0, 0.01] {
        let o = pmc_options_new();
        unsafe { assert_eq!(pmc_options_set_epsilon(o, eps), PmcStatus::Ok) };
        let ro = Options {
            epsilon: eps,
            ..Options::default()
        };
        let rm = extract(&rv, 5.5, &ro).unwrap();
        let cm = c_extract(&cv, 5.5, o).unwrap();
        unsafe { pmc_options_free(o) };
        // World points, computed on first request by several threads at
        // once: one array, bit-identical to the Rust API's.
        let addrs: Vec<usize> = std::thread::scope(|s| {
            let h = cm.0 as usize;
            let jobs: Vec<_> = (0..4)
                .map(|_| s.spawn(move || unsafe { pmc_mesh_points(h as *const pmc_mesh) } as usize))
                .collect();
            jobs.into_iter().map(|j| j.join().unwrap()).collect()
        });
        assert!(addrs[0] != 0 && addrs.iter().all(|&a| a == addrs[0]));
        cm.assert_equals(&rm);

        let nt = unsafe { pmc_mesh_triangle_count(cm.0) };
        let mut count = u64::MAX;
        let taken = unsafe { pmc_mesh_take_triangles(cm.0, &mut count) };
        assert_eq!(count, nt);
        assert_eq!(count, rm.triangles.len() as u64);
        let flat: Vec<i64> = rm.triangles.iter().flatten().map(|&i| i as i64).collect();
        assert_eq!(
            unsafe { std::slice::from_raw_parts(taken, 3 * nt as usize) },
            &flat[..]
        );
        // The mesh keeps everything else.
        unsafe {
            assert_eq!(pmc_mesh_triangle_count(cm.0), 0);
            assert!(pmc_mesh_triangles(cm.0).is_null());
            assert_eq!(pmc_mesh_point_count(cm.0), rm.index_points.len() as u64);
            let levels = pmc_mesh_triangle_levels(cm.0);
            assert_eq!(
                std::slice::from_raw_parts(levels, nt as usize),
                &rm.levels[..]
            );
            let mut st = pmc_stats::default();
            assert_eq!(pmc_mesh_stats(cm.0, &mut st), PmcStatus::Ok);
            assert_eq!(st.output_triangles, nt);
            // Nothing left to take; NULL is accepted.
            let mut again = 7;
            assert!(pmc_mesh_take_triangles(cm.0, &mut again).is_null());
            assert_eq!(again, 0);
            assert!(pmc_mesh_take_triangles(ptr::null_mut(), ptr::null_mut()).is_null());
        }
        // The array outlives its mesh.
        drop(cm);
        assert_eq!(
            unsafe { *taken.add(3 * nt as usize - 1) },
            flat[flat.len() - 1]
        );
        unsafe { pmc_buffer_free(taken.cast()) };
    }
}

#[test]
fn index_offset_and_strides_equal_rust_api() {
    let n = 14;
    let data = sphere(n, [6.0, 6.5, 7.0]);
    // x and z swapped in memory: strides (n*n, n, 1).
    let mut swapped = vec![0f32; data.len()];
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                swapped[((i * n + j) * n + k) as usize] = data[((k * n + j) * n + i) as usize];
            }
        }
    }
    let mut cv = c_volume(&swapped, [n, n, n]);
    cv.strides = [(n * n) as i64, n as i64, 1];
    let offset = [-3i64, 10, 1 << 20];
    let rv = Volume::new(&data, [n, n, n])
        .with_origin(cv.origin)
        .with_spacing(cv.spacing)
        .with_index_offset(offset);
    let o = pmc_options_new();
    assert_eq!(
        unsafe { pmc_options_set_index_offset(o, offset.as_ptr()) },
        PmcStatus::Ok
    );
    let cm = c_extract(&cv, 4.5, o).unwrap();
    cm.assert_equals(&extract(&rv, 4.5, &Options::default()).unwrap());
    unsafe { pmc_options_free(o) };
}

#[test]
fn every_scalar_type_equals_rust_api() {
    let n = 10u64;
    let base: Vec<f64> = sphere(n, [4.5, 4.2, 4.9])
        .iter()
        .map(|&x| (x * 10.0).round() as f64)
        .collect();
    // Values around 0 for the signed types and across the signed maximum
    // for the unsigned ones (scaled where f64 steps are coarse there), so
    // that a sample read with the wrong signedness changes the surface.
    macro_rules! check {
        ($t:ty, $st:expr, $scale:expr, $shift:expr) => {{
            let (scale, shift): (f64, f64) = ($scale, $shift);
            let d: Vec<$t> = base.iter().map(|&x| (x * scale + shift) as $t).collect();
            // (Below 0, or the signed maximum, and above it.)
            let edge = shift + 40.0 * scale;
            assert!(d.iter().any(|&v| (v as f64) < edge) && d.iter().any(|&v| v as f64 >= edge));
            let iso = 35.5 * scale + shift;
            let cv = pmc_volume {
                struct_size: std::mem::size_of::<pmc_volume>() as u64,
                data: d.as_ptr().cast(),
                len: d.len() as u64,
                scalar_type: $st as u32,
                dims: [n; 3],
                strides: [0; 3],
                origin: [0.0; 3],
                spacing: [1.0; 3],
            };
            let cm = c_extract(&cv, iso, ptr::null()).unwrap();
            let rm = extract(&Volume::new(&d, [n; 3]), iso, &Options::default()).unwrap();
            assert!(rm.triangles.len() > 100, "{}", stringify!($t));
            cm.assert_equals(&rm);
        }};
    }
    check!(i8, PmcScalarType::I8, 1.0, -40.0);
    check!(u8, PmcScalarType::U8, 1.0, 128.0 - 40.0);
    check!(i16, PmcScalarType::I16, 1.0, -40.0);
    check!(u16, PmcScalarType::U16, 1.0, 32768.0 - 40.0);
    check!(i32, PmcScalarType::I32, 1.0, -40.0);
    check!(u32, PmcScalarType::U32, 1.0, 2147483648.0 - 40.0);
    check!(i64, PmcScalarType::I64, 1.0, -40.0);
    check!(
        u64,
        PmcScalarType::U64,
        4096.0,
        9223372036854775808.0 - 40.0 * 4096.0
    );
    check!(f32, PmcScalarType::F32, 1.0, -40.0);
    check!(f64, PmcScalarType::F64, 1.0, -40.0);
}

unsafe extern "C" fn record(user_data: *mut c_void, fraction: f64) -> c_int {
    let v = unsafe { &mut *user_data.cast::<Vec<f64>>() };
    v.push(fraction);
    0
}

#[test]
fn progress_matches_rust_and_is_monotone() {
    let n = 40;
    let data = sphere(n, [19.5, 19.5, 19.5]);
    let cv = c_volume(&data, [n, n, n]);
    let mut seen: Vec<f64> = Vec::new();
    let o = pmc_options_new();
    unsafe {
        assert_eq!(
            pmc_options_set_progress(o, Some(record), (&mut seen as *mut Vec<f64>).cast()),
            PmcStatus::Ok
        );
        assert_eq!(pmc_options_set_max_triangles(o, 20000), PmcStatus::Ok);
        assert_eq!(pmc_options_set_epsilon(o, 0.0005), PmcStatus::Ok);
    }
    let cm = c_extract(&cv, 12.0, o).unwrap();
    assert_eq!(seen.first(), Some(&0.0));
    assert_eq!(seen.last(), Some(&1.0));
    assert!(seen.windows(2).all(|w| w[0] <= w[1]), "{seen:?}");
    // Same mesh as the Rust API with a progress closure.
    let rv = Volume::new(&data, [n, n, n])
        .with_origin(cv.origin)
        .with_spacing(cv.spacing);
    let ro = Options {
        max_triangles: 20000,
        epsilon: 0.0005,
        ..Options::default()
    };
    let rm = extract_with_progress(&rv, 12.0, &ro, &mut |_| ControlFlow::Continue(())).unwrap();
    cm.assert_equals(&rm);
    unsafe { pmc_options_free(o) };
}

#[test]
fn errors_map_to_statuses_with_messages() {
    let data = sphere(6, [2.5, 2.5, 2.5]);
    let mut cv = c_volume(&data, [6, 6, 6]);
    assert_eq!(
        c_extract(&cv, f64::NAN, ptr::null()).err(),
        Some(PmcStatus::InvalidArgument)
    );
    assert!(
        last_error().contains("isovalue NaN is not finite"),
        "{}",
        last_error()
    );
    cv.dims[1] = 1;
    assert_eq!(
        c_extract(&cv, 2.0, ptr::null()).err(),
        Some(PmcStatus::InvalidArgument)
    );
    assert!(
        last_error().contains("dimension 1 (y) is 1"),
        "{}",
        last_error()
    );
    cv.dims[1] = 6;
    cv.len -= 1;
    assert_eq!(
        c_extract(&cv, 2.0, ptr::null()).err(),
        Some(PmcStatus::InvalidArgument)
    );
    assert!(
        last_error().contains("outside the buffer"),
        "{}",
        last_error()
    );
    cv.len += 1;
    // An index offset beyond ±2^31: its own message, naming axis and value.
    let o = pmc_options_new();
    for (axis, value) in [(2, PMC_MAX_INDEX_OFFSET + 1), (0, i64::MIN)] {
        let mut off = [0i64; 3];
        off[axis] = value;
        assert_eq!(
            unsafe { pmc_options_set_index_offset(o, off.as_ptr()) },
            PmcStatus::Ok
        );
        assert_eq!(
            c_extract(&cv, 2.0, o).err(),
            Some(PmcStatus::InvalidArgument)
        );
        assert_eq!(
            last_error(),
            format!(
                "invalid options: index offset {axis} ({}) is {value}; index offsets must lie \
                 in -2147483648..=2147483648 (2^31) (pmc_options_set_index_offset)",
                ["x", "y", "z"][axis]
            )
        );
    }
    let off = [PMC_MAX_INDEX_OFFSET, -PMC_MAX_INDEX_OFFSET, 0];
    assert_eq!(
        unsafe { pmc_options_set_index_offset(o, off.as_ptr()) },
        PmcStatus::Ok
    );
    assert!(c_extract(&cv, 2.0, o).is_ok());
    unsafe { pmc_options_free(o) };
    // A world box that overflows.
    let mut huge = cv;
    huge.origin[0] = 1e308;
    huge.spacing[0] = 1e308;
    assert_eq!(
        c_extract(&huge, 2.0, ptr::null()).err(),
        Some(PmcStatus::InvalidArgument)
    );
    assert!(last_error().contains("is not finite"), "{}", last_error());
    cv.scalar_type = 77;
    assert_eq!(
        c_extract(&cv, 2.0, ptr::null()).err(),
        Some(PmcStatus::InvalidArgument)
    );
    assert_eq!(last_error(), "unknown scalar type 77");
    cv.scalar_type = PmcScalarType::F32 as u32;
    cv.data = ptr::null();
    assert_eq!(
        c_extract(&cv, 2.0, ptr::null()).err(),
        Some(PmcStatus::NullArgument)
    );
    assert_eq!(last_error(), "volume->data is NULL");
    // NULL data is named first, whatever else is wrong.
    cv.scalar_type = 77;
    assert_eq!(
        c_extract(&cv, 2.0, ptr::null()).err(),
        Some(PmcStatus::NullArgument)
    );
    assert_eq!(last_error(), "volume->data is NULL");
    let status = unsafe { CStr::from_ptr(pmc_status_string(PmcStatus::Aborted as u32)) };
    assert_eq!(status.to_str().unwrap(), "aborted by the progress callback");
}

/// `pmc_options_set_gradients` takes 0 or 1 only, as the setters of
/// enumerations take their values only; `pmc_mesh_gradients` is `NULL`
/// unless gradients were asked for.
#[test]
fn gradients_flag_is_checked_and_gradients_come_on_request() {
    assert_eq!(
        unsafe { pmc_options_set_gradients(ptr::null_mut(), 1) },
        PmcStatus::NullArgument
    );
    assert_eq!(last_error(), "options is NULL");
    assert!(unsafe { pmc_mesh_gradients(ptr::null()) }.is_null());
    let data = sphere(8, [3.5, 3.5, 3.5]);
    let cv = c_volume(&data, [8, 8, 8]);
    let o = pmc_options_new();
    // Off by default.
    let m = c_extract(&cv, 2.0, o).unwrap();
    assert!(unsafe { pmc_mesh_point_count(m.0) } > 0);
    assert!(unsafe { pmc_mesh_gradients(m.0) }.is_null());
    assert_eq!(unsafe { pmc_options_set_gradients(o, 1) }, PmcStatus::Ok);
    for bad in [2, -1, c_int::MAX] {
        assert_eq!(
            unsafe { pmc_options_set_gradients(o, bad) },
            PmcStatus::InvalidArgument
        );
        assert_eq!(
            last_error(),
            format!("gradients must be 0 (off) or 1 (on), not {bad}")
        );
    }
    // Still on: the rejected values left the options unchanged.
    let m = c_extract(&cv, 2.0, o).unwrap();
    assert!(!unsafe { pmc_mesh_gradients(m.0) }.is_null());
    assert!(unsafe { pmc_mesh_normals(m.0) }.is_null());
    assert_eq!(unsafe { pmc_options_set_gradients(o, 0) }, PmcStatus::Ok);
    let m = c_extract(&cv, 2.0, o).unwrap();
    assert!(unsafe { pmc_mesh_gradients(m.0) }.is_null());
    unsafe { pmc_options_free(o) };
}

#[test]
fn last_error_is_per_thread_and_calls_are_thread_safe() {
    let n = 16;
    let data = sphere(n, [7.5, 7.5, 7.5]);
    let cv = c_volume(&data, [n, n, n]);
    let o = pmc_options_new();
    unsafe { assert_eq!(pmc_options_set_epsilon(o, -1.0), PmcStatus::InvalidArgument) };
    let main_msg = last_error();
    assert!(main_msg.contains("epsilon"));
    let reference = extract(
        &Volume::new(&data, [n, n, n])
            .with_origin(cv.origin)
            .with_spacing(cv.spacing),
        6.0,
        &Options::default(),
    )
    .unwrap();
    // Raw pointers: the C API documents volumes and options as shareable.
    struct Shared(pmc_volume, *const pmc_options);
    unsafe impl Sync for Shared {}
    let shared = Shared(cv, o);
    std::thread::scope(|s| {
        for t in 0..4 {
            let (reference, shared) = (&reference, &shared);
            s.spawn(move || {
                let cv = &shared.0;
                assert_eq!(last_error(), "", "fresh thread has no error");
                if t % 2 == 0 {
                    let mut bad = *cv;
                    bad.spacing[2] = -1.0;
                    assert_eq!(
                        c_extract(&bad, 6.0, shared.1).err(),
                        Some(PmcStatus::InvalidArgument)
                    );
                    assert!(last_error().contains("spacing 2 (z) is -1"));
                }
                c_extract(cv, 6.0, shared.1)
                    .unwrap()
                    .assert_equals(reference);
            });
        }
    });
    assert_eq!(last_error(), main_msg);
    unsafe { pmc_options_free(o) };
}

/// A struct of the C API followed by bytes it does not know: what a caller
/// built against a later header, whose struct has more fields, passes.
#[repr(C)]
struct Bigger<T> {
    known: T,
    tail: [u8; 40],
}

const CANARY: u8 = 0xA5;

/// `Bigger<T>` with every byte `CANARY` and `struct_size` (the first 8
/// bytes) `size`.
fn canaried<T>(size: u64) -> Box<Bigger<T>> {
    let mut b = Box::new(std::mem::MaybeUninit::<Bigger<T>>::uninit());
    unsafe {
        ptr::write_bytes(b.as_mut_ptr().cast::<u8>(), CANARY, size_of::<Bigger<T>>());
        b.as_mut_ptr().cast::<u64>().write(size);
        Box::from_raw(Box::into_raw(b).cast::<Bigger<T>>())
    }
}

fn bytes<T>(b: &Bigger<T>) -> &[u8] {
    unsafe { std::slice::from_raw_parts((b as *const Bigger<T>).cast(), size_of::<Bigger<T>>()) }
}

/// `struct_size`, the first field of `pmc_volume`, `pmc_stats` and
/// `pmc_distance`: 0 and sizes below the version 1 layout are rejected
/// with a message naming the field, before anything else is read or
/// written; a larger size is accepted, and output structs get every field
/// they know written and no byte past them, nor `struct_size`.
#[test]
fn struct_size_is_checked_and_respected() {
    let data = sphere(8, [3.5, 3.5, 3.0]);
    let cv = c_volume(&data, [8, 8, 8]);
    let want = c_extract(&cv, 2.5, ptr::null()).unwrap();
    let mut want_stats = pmc_stats::default();
    assert_eq!(
        unsafe { pmc_mesh_stats(want.0, &mut want_stats) },
        PmcStatus::Ok
    );
    assert_eq!(want_stats.struct_size, 152, "Default sets struct_size");
    assert!(want_stats.output_triangles > 0);
    let (np, nt) = unsafe {
        (
            pmc_mesh_point_count(want.0),
            pmc_mesh_triangle_count(want.0),
        )
    };
    let points = want
        .slice(unsafe { pmc_mesh_points(want.0) }, 3 * np)
        .to_vec();
    let tris = want
        .slice(unsafe { pmc_mesh_triangles(want.0) }, 3 * nt)
        .to_vec();
    let measure = |v: *const pmc_volume, iso: f64, out: *mut pmc_distance| unsafe {
        pmc_measure_distance(v, iso, points.as_ptr(), np, tris.as_ptr(), nt, 1, out)
    };
    let mut want_dist = pmc_distance::default();
    assert_eq!(measure(&cv, 2.5, &mut want_dist), PmcStatus::Ok);
    assert_eq!(want_dist.struct_size, 48, "Default sets struct_size");
    assert!(want_dist.samples > 0);

    let rejected = |name: &str, size: u64| {
        let msg = last_error();
        assert!(
            msg.starts_with(&format!("{name}.struct_size is {size}")),
            "{msg}"
        );
        assert!(msg.contains(&format!("set it to sizeof({name})")), "{msg}");
    };

    // Input: pmc_volume. (Above 64 KiB: a pointer, from a caller built
    // against a header without struct_size.)
    let pointer_like = &cv as *const pmc_volume as u64;
    for size in [0, 1, 127, (1 << 16) + 1, pointer_like] {
        let mut v = cv;
        v.struct_size = size;
        assert_eq!(
            c_extract(&v, 2.5, ptr::null()).err(),
            Some(PmcStatus::InvalidArgument)
        );
        rejected("pmc_volume", size);
        // Before any other field: a NULL data is not what is reported.
        v.data = ptr::null();
        assert_eq!(
            c_extract(&v, 2.5, ptr::null()).err(),
            Some(PmcStatus::InvalidArgument)
        );
        rejected("pmc_volume", size);
        let mut d = pmc_distance::default();
        assert_eq!(measure(&v, 2.5, &mut d), PmcStatus::InvalidArgument);
        rejected("pmc_volume", size);
    }
    // A larger volume (a later header's): its tail is not read.
    let mut big = canaried::<pmc_volume>(size_of::<Bigger<pmc_volume>>() as u64);
    big.known = pmc_volume {
        struct_size: size_of::<Bigger<pmc_volume>>() as u64,
        ..cv
    };
    let got = c_extract(&big.known, 2.5, ptr::null()).unwrap();
    let mut got_stats = pmc_stats::default();
    assert_eq!(
        unsafe { pmc_mesh_stats(got.0, &mut got_stats) },
        PmcStatus::Ok
    );
    assert_eq!(
        (got_stats.output_triangles, got_stats.output_points),
        (want_stats.output_triangles, want_stats.output_points)
    );
    let mut d = pmc_distance::default();
    assert_eq!(measure(&big.known, 2.5, &mut d), PmcStatus::Ok);
    assert_eq!(d, want_dist);

    // Outputs, rejected: nothing written.
    let v1_stats = size_of::<pmc_stats>() as u64;
    for size in [0, 1, v1_stats - 1, (1 << 16) + 1] {
        let mut b = canaried::<pmc_stats>(size);
        assert_eq!(
            unsafe { pmc_mesh_stats(want.0, &mut b.known) },
            PmcStatus::InvalidArgument
        );
        rejected("pmc_stats", size);
        assert!(bytes(&b)[8..].iter().all(|&x| x == CANARY));
        assert_eq!(b.known.struct_size, size);
    }
    let v1_dist = size_of::<pmc_distance>() as u64;
    for size in [0, 1, v1_dist - 1, (1 << 16) + 1] {
        let mut b = canaried::<pmc_distance>(size);
        assert_eq!(measure(&cv, 2.5, &mut b.known), PmcStatus::InvalidArgument);
        rejected("pmc_distance", size);
        assert!(bytes(&b)[8..].iter().all(|&x| x == CANARY));
        assert_eq!(b.known.struct_size, size);
        // Checked before the volume.
        assert_eq!(
            measure(ptr::null(), 2.5, &mut b.known),
            PmcStatus::InvalidArgument
        );
        rejected("pmc_distance", size);
    }

    // Outputs of exactly the version 1 size, then larger: every field
    // written, struct_size kept, no byte past the version 1 layout.
    for size in [v1_stats, size_of::<Bigger<pmc_stats>>() as u64] {
        let mut b = canaried::<pmc_stats>(size);
        assert_eq!(
            unsafe { pmc_mesh_stats(want.0, &mut b.known) },
            PmcStatus::Ok
        );
        assert_eq!(b.known.struct_size, size);
        assert_eq!(
            pmc_stats {
                struct_size: want_stats.struct_size,
                ..b.known
            },
            want_stats
        );
        assert!(b.tail.iter().all(|&x| x == CANARY));
    }
    for size in [v1_dist, size_of::<Bigger<pmc_distance>>() as u64] {
        let mut b = canaried::<pmc_distance>(size);
        assert_eq!(measure(&cv, 2.5, &mut b.known), PmcStatus::Ok);
        assert_eq!(b.known.struct_size, size);
        assert_eq!(
            pmc_distance {
                struct_size: want_dist.struct_size,
                ..b.known
            },
            want_dist
        );
        assert!(b.tail.iter().all(|&x| x == CANARY));
        // A later failure zeroes the known fields, and only those.
        let mut b = canaried::<pmc_distance>(size);
        assert_eq!(
            measure(&cv, f64::NAN, &mut b.known),
            PmcStatus::InvalidArgument
        );
        assert_eq!(b.known.struct_size, size);
        assert_eq!(
            b.known,
            pmc_distance {
                struct_size: size,
                ..pmc_distance::default()
            }
        );
        assert!(b.tail.iter().all(|&x| x == CANARY));
    }

    // pmc_stats need not be aligned.
    let mut buf = vec![CANARY; 1 + v1_stats as usize + 40];
    let out = unsafe { buf.as_mut_ptr().add(1) };
    unsafe { out.cast::<u64>().write_unaligned(v1_stats) };
    assert_eq!(unsafe { pmc_mesh_stats(want.0, out.cast()) }, PmcStatus::Ok);
    let s = unsafe { out.cast::<pmc_stats>().read_unaligned() };
    assert_eq!(s, want_stats);
    assert_eq!(buf[0], CANARY);
    assert!(buf[1 + v1_stats as usize..].iter().all(|&x| x == CANARY));
}
