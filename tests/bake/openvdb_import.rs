//! OpenVDB volumes in, against files OpenVDB's own library wrote
//! (`tests/data/openvdb/make_vdbs.py`, Debian's python3-openvdb 10.0, Blosc-compressed as it
//! writes by default): a level set sphere against the analytic sphere, a fog volume against
//! the formula that filled it (in full and half precision), its colour grid, and broken,
//! unsupported and oversized input refused by name without a panic.

use mesobake_bake::mesostructure::openvdb::{VdbImport, VdbImported, import};
use mesobake_bake::mesostructure::volume::Volume;
use mesobake_core::limits::Limits;
use mesobake_package::grid::Dims;
use std::path::Path;

fn file(name: &str) -> Vec<u8> {
    std::fs::read(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data/openvdb")
            .join(name),
    )
    .unwrap()
}

fn imported(name: &str, options: VdbImport) -> (Volume, VdbImported) {
    import(&file(name), &options, &Limits::default()).unwrap()
}

fn refusal(bytes: &[u8], options: VdbImport, limits: &Limits) -> String {
    import(bytes, &options, limits).unwrap_err().to_string()
}

/// The sphere's parameters in make_vdbs.py.
const CENTRE: [f64; 3] = [4.1, 3.9, 3.05];
const RADIUS: f64 = 3.1;
const VOXEL: f64 = 0.25;

/// Every voxel of the imported box is solid exactly where its VDB index point lies inside
/// the sphere (voxels within 1e-4 world units of the surface, where φ's float rounding
/// decides, are skipped: 6 in this file): both for the active bounding box and for a box
/// from the origin that cuts the sphere.
#[test]
fn a_level_set_imports_as_the_voxels_inside_its_analytic_sphere() {
    for res in [None, Some(Dims::new(32, 24, 20).unwrap())] {
        let (volume, report) = imported(
            "sphere.vdb",
            VdbImport {
                res,
                ..VdbImport::default()
            },
        );
        assert_eq!(report.grid, "surface");
        assert_eq!(report.class, "level set");
        assert_eq!(report.voxel_size, VOXEL);
        let dims = volume.dims();
        match res {
            None => {
                // The narrow band (3 voxels) around the sphere, as OpenVDB records it.
                assert_eq!(report.origin, [2, 1, -3]);
                assert_eq!(report.dims, [30, 30, 31]);
            }
            Some(d) => assert_eq!((report.origin, dims), ([0; 3], d)),
        }
        let (mut solid, mut skipped) = (0, 0);
        for k in 0..dims.z {
            for j in 0..dims.y {
                for i in 0..dims.x {
                    let p = [i, j, k].map(f64::from);
                    let o = report.origin.map(f64::from);
                    let distance = (0..3)
                        .map(|a| ((o[a] + p[a]) * VOXEL - CENTRE[a]).powi(2))
                        .sum::<f64>()
                        .sqrt()
                        - RADIUS;
                    if distance.abs() < 1e-4 {
                        skipped += 1;
                        continue;
                    }
                    assert_eq!(
                        volume.is_solid(i, j, k),
                        distance < 0.0,
                        "voxel ({i}, {j}, {k}) is {distance} from the surface"
                    );
                    solid += u32::from(distance < 0.0);
                }
            }
        }
        assert!(skipped <= 6, "{skipped} voxels on the surface");
        // The sphere holds 4/3·π·12.4³ ≈ 7986 voxels' volume; cut at z = 0, less.
        let expected = if res.is_none() {
            7000..9000
        } else {
            3000..7000
        };
        assert!(expected.contains(&solid), "{solid} solid voxels");
    }
}

/// The density the file was filled with, at index `p` (make_vdbs.py).
fn density(p: [i32; 3]) -> f64 {
    let s = |t: f64| (std::f64::consts::PI * t).sin().powi(2);
    let [i, j, k] = [p[0] - 5, p[1] + 3, p[2] - 2].map(f64::from);
    if !((0.0..16.0).contains(&i) && (0.0..16.0).contains(&j) && (0.0..8.0).contains(&k)) {
        return 0.0;
    }
    4.0 * s(i / 15.0) * s(j / 15.0) * s(k / 7.0)
}

/// Each voxel's opacity is 1 − exp(−s·ρ·h) of the density written there (h = 0.125; within
/// 1e-6 at full precision, 1e-3 from half floats, whose 11-bit mantissa rounds ρ), scaled
/// by the density scale; the albedo is the colour grid's (i/15, j/15, ½) in sRGB bytes
/// (within one step).
#[test]
fn a_fog_volume_imports_its_density_as_opacity_per_voxel_length_with_its_colour() {
    for (grid, scale, tolerance) in [
        (None, 1.0, 1e-6),
        (Some("density_half"), 1.0, 1e-3),
        (None, 3.0, 1e-6),
    ] {
        let options = VdbImport {
            grid: grid.map(String::from),
            density_scale: scale,
            ..VdbImport::default()
        };
        let (volume, report) = imported("fog.vdb", options);
        assert_eq!(report.grid, grid.unwrap_or("density"));
        assert_eq!(report.class, "fog volume");
        assert_eq!(report.color_grid.as_deref(), Some("Cd"));
        // Index 5 (and y = −3) hold density 0: inactive, outside the active box.
        assert_eq!((report.origin, report.dims), ([6, -2, 3], [15, 15, 7]));
        let dims = volume.dims();
        let (opacity, albedo) = (volume.opacity().unwrap(), volume.albedo().unwrap());
        let mut worst = 0.0f64;
        for k in 0..dims.z {
            for j in 0..dims.y {
                for i in 0..dims.x {
                    let p = [6 + i as i32, -2 + j as i32, 3 + k as i32];
                    let expected = 1.0 - (-scale * density(p) * 0.125).exp();
                    let v = dims.index(i, j, k);
                    worst = worst.max((f64::from(opacity[v]) - expected).abs());
                    let colour = [f64::from(p[0] - 5) / 15.0, f64::from(p[1] + 3) / 15.0, 0.5];
                    for c in 0..3 {
                        let srgb =
                            f64::from(mesobake_core::color::linear_to_srgb(colour[c] as f32));
                        assert!(
                            (f64::from(albedo[v][c]) - srgb * 255.0).abs() <= 1.0,
                            "{p:?}"
                        );
                    }
                }
            }
        }
        assert!(worst <= tolerance, "{grid:?}: worst opacity error {worst}");
    }
}

/// Grids mesobake does not import, a missing name, a box over the memory limit, a file cut
/// anywhere and files with bytes overwritten: each an error naming the problem, none a panic.
#[test]
fn unsupported_grids_and_broken_files_are_refused_by_name() {
    let fog = file("fog.vdb");
    let limits = Limits::default();
    let grid = |name: &str| VdbImport {
        grid: Some(name.into()),
        ..VdbImport::default()
    };
    let e = refusal(&fog, grid("mask"), &limits);
    assert!(e.contains("\"mask\" is of type Tree_bool_5_4_3"), "{e}");
    let e = refusal(&fog, grid("Cd"), &limits);
    assert!(e.contains("\"Cd\" holds Vec3s values"), "{e}");
    let e = refusal(&fog, grid("smoke"), &limits);
    assert!(
        e.contains("no grid is named \"smoke\"") && e.contains("\"density_half\""),
        "{e}"
    );
    let e = refusal(b"\x20BDV\0\0\0\0\xff\0\0\0", VdbImport::default(), &limits);
    assert!(e.contains("file format version 255"), "{e}");
    let e = refusal(b"not a vdb", VdbImport::default(), &limits);
    assert!(e.contains("not an OpenVDB file"), "{e}");
    let huge = VdbImport {
        res: Some(Dims::new(4096, 4096, 4096).unwrap()),
        ..VdbImport::default()
    };
    let e = refusal(&fog, huge, &limits);
    assert!(e.contains("the imported volume"), "{e}");
    // The tree alone over a small limit (the box is tiny).
    let tiny = Limits {
        memory_bytes: 200_000,
        ..Limits::default()
    };
    let small_box = VdbImport {
        res: Some(Dims::new(2, 2, 2).unwrap()),
        ..VdbImport::default()
    };
    let e = refusal(&file("sphere.vdb"), small_box, &tiny);
    assert!(e.contains("over the memory limit"), "{e}");
    // By default the box is the recorded bounds (30×30×31 voxels, 11 bytes each), refused
    // from the header before the tree is read.
    let e = refusal(&file("sphere.vdb"), VdbImport::default(), &tiny);
    assert!(
        e.contains("the imported volume") && e.contains("306900"),
        "{e}"
    );

    let sphere = file("sphere.vdb");
    for cut in (0..sphere.len()).step_by(97) {
        import(&sphere[..cut], &VdbImport::default(), &limits).unwrap_err();
    }
    // Overwritten bytes: an error or a (wrong) volume, never a panic or a read outside the
    // file. A fixed-seed xorshift picks the bytes.
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    for _ in 0..3000 {
        let mut mutant = sphere.clone();
        for _ in 0..1 + next() % 4 {
            let at = (next() % mutant.len() as u64) as usize;
            mutant[at] = next() as u8;
        }
        let _ = import(&mutant, &VdbImport::default(), &limits);
    }
}

/// The colour grid's tree is read under what the density's tree left of the memory limit:
/// both fit at the file's bytes plus their sum, and not at one byte less.
#[test]
fn the_colour_tree_is_read_under_what_the_density_tree_left() {
    use mesobake_bake::mesostructure::openvdb::archive::Archive;
    use mesobake_bake::mesostructure::openvdb::tree::Tree;
    let fog = file("fog.vdb");
    let archive = Archive::read(&fog).unwrap();
    let (_, report) = imported("fog.vdb", VdbImport::default());
    let density = Tree::read(&fog, archive.grid("density").unwrap(), u64::MAX, |_| true)
        .unwrap()
        .bytes();
    // The colour's leaves that meet the imported box, as the import keeps them.
    let (o, d) = (report.origin, report.dims);
    let meets = |leaf: [i32; 3]| {
        (0..3).all(|a| leaf[a] + 8 > o[a] && i64::from(leaf[a]) < i64::from(o[a]) + i64::from(d[a]))
    };
    let colour = Tree::read(&fog, archive.grid("Cd").unwrap(), u64::MAX, meets)
        .unwrap()
        .bytes();
    let enough = fog.len() as u64 + density + colour;
    let at = |memory_bytes| {
        let limits = Limits {
            memory_bytes,
            ..Limits::default()
        };
        import(&fog, &VdbImport::default(), &limits)
    };
    at(enough).unwrap();
    let e = at(enough - 1).unwrap_err().to_string();
    assert!(
        e.contains("\"Cd\"") && e.contains("over the memory limit"),
        "{e}"
    );
}
