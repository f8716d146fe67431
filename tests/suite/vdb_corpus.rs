//! Reads every grid of the shared VDB corpus and compares it with what OpenVDB C++ reports (`truth.tsv`).

use crate::common;

use glam::IVec3;
use nimbus::vdb::{file_info, FloatTree, GridInfo, Region};
use regions_check::{active_voxels_of_regions, check_regions_in};

/// The region checks the VDB unit tests use too (they need `FloatTree`, `Region` and `IVec3` in scope here).
#[path = "../support/regions.rs"]
mod regions_check;

fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * a.abs().max(b.abs()) + 1e-300
}

fn ivec(s: &str) -> [i32; 3] {
    let v: Vec<i32> = s.split(',').map(|x| x.trim().parse().unwrap()).collect();
    [v[0], v[1], v[2]]
}

fn check(g: &GridInfo, t: &[&str], what: &str) {
    assert_eq!(g.name, t[1], "{what}: name");
    let type_name = match g.value_type.as_str() {
        "float" => "Tree_float_5_4_3",
        "double" => "Tree_double_5_4_3",
        _ => "Tree_vec3s_5_4_3",
    };
    assert_eq!(type_name, t[2], "{what}: type");
    assert_eq!(g.half, t[3] == "1", "{what}: half");
    assert_eq!(
        g.stats.active_voxels,
        t[4].parse::<u64>().unwrap(),
        "{what}: active"
    );
    assert_eq!(
        g.stats.leaf_voxels,
        t[5].parse::<u64>().unwrap(),
        "{what}: leaf voxels"
    );
    assert_eq!(g.stats.tiles, t[6].parse::<u64>().unwrap(), "{what}: tiles");
    assert_eq!(
        g.stats.leaves,
        t[7].parse::<u64>().unwrap(),
        "{what}: leaves"
    );
    let sum: f64 = t[8].parse().unwrap();
    assert!(
        close(g.stats.sum, sum, 1e-5),
        "{what}: sum {} vs {sum}",
        g.stats.sum
    );
    let (mn, mx): (f64, f64) = (t[9].parse().unwrap(), t[10].parse().unwrap());
    assert!(
        close(g.stats.min, mn, 1e-6),
        "{what}: min {} vs {mn}",
        g.stats.min
    );
    assert!(
        close(g.stats.max, mx, 1e-6),
        "{what}: max {} vs {mx}",
        g.stats.max
    );
    let (bmin, bmax) = g.stats.bbox.unwrap_or_default();
    assert_eq!(bmin.to_array(), ivec(t[11]), "{what}: bbox min");
    assert_eq!(bmax.to_array(), ivec(t[12]), "{what}: bbox max");
    let vs: f64 = t[14].parse().unwrap();
    assert!(
        close(g.voxel_size[0], vs, 1e-6),
        "{what}: voxel size {:?} vs {vs}",
        g.voxel_size
    );
    if type_name != "Tree_vec3s_5_4_3" {
        let bg: f64 = t[15].parse().unwrap();
        match g.background {
            nimbus::vdb::Background::Float(b) => {
                assert!(close(b as f64, bg, 1e-6), "{what}: background")
            }
            _ => panic!("{what}: vector background on a scalar grid"),
        }
    }
    let m: Vec<f64> = t[16].split(',').map(|x| x.parse().unwrap()).collect();
    for r in 0..4 {
        for c in 0..4 {
            // truth is row-vector (M_r), ours column-vector: ours[r][c] == truth[c][r].
            let (a, b) = (g.index_to_world[r * 4 + c], m[c * 4 + r]);
            assert!(
                (a - b).abs() <= 1e-6 * (1.0 + b.abs()),
                "{what}: matrix[{r}][{c}] {a} vs {b}"
            );
        }
    }
}

#[test]
fn corpus_matches_openvdb() {
    let Some(dir) = common::vdb_corpus_dir() else {
        return;
    };
    let truth = std::fs::read_to_string(dir.join("truth.tsv")).unwrap();
    let mut files: Vec<(String, Vec<Vec<&str>>)> = Vec::new();
    for line in truth.lines().skip(1).filter(|l| !l.trim().is_empty()) {
        let cols: Vec<&str> = line.split('\t').collect();
        assert!(cols.len() >= 17, "bad truth line {line}");
        match files.last_mut() {
            Some((f, v)) if f == cols[0] => v.push(cols),
            _ => files.push((cols[0].to_string(), vec![cols])),
        }
    }
    assert!(!files.is_empty());
    for (file, lines) in &files {
        let info = file_info(&dir.join(file)).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(info.grids.len(), lines.len(), "{file}: grid count");
        for (i, (g, t)) in info.grids.iter().zip(lines).enumerate() {
            check(g, t, &format!("{file} grid {i}"));
        }
        eprintln!("ok {file}");
    }
}

/// An instanced grid (sharing its parent's tree) is synthesised from `f_affine.vdb` in memory: a second
/// descriptor with an instance parent, followed by compression flags, empty metadata and a transform.
#[test]
fn instanced_grid_shares_parent_tree() {
    let Some(dir) = common::vdb_corpus_dir() else {
        return;
    };
    let mut data = std::fs::read(dir.join("generated/f_affine.vdb")).unwrap();
    let find = |d: &[u8], pat: &[u8]| d.windows(pat.len()).position(|w| w == pat).unwrap();
    let desc = find(
        &data,
        b"\x07\x00\x00\x00density\x10\x00\x00\x00Tree_float_5_4_3",
    );
    let count_at = desc - 4;
    assert_eq!(&data[count_at..desc], &1i32.to_le_bytes());
    data[count_at..desc].copy_from_slice(&2i32.to_le_bytes());
    let map = find(&data, b"\x09\x00\x00\x00AffineMap");
    let transform = data[map..map + 4 + 9 + 128].to_vec();
    let grid_at = desc + 35;
    let compression = data
        [i64::from_le_bytes(data[grid_at..grid_at + 8].try_into().unwrap()) as usize..][..4]
        .to_vec();

    let mut extra = Vec::new();
    for s in ["inst", "Tree_float_5_4_3", "density"] {
        extra.extend_from_slice(&(s.len() as u32).to_le_bytes());
        extra.extend_from_slice(s.as_bytes());
    }
    let grid_pos = (data.len() + extra.len() + 24) as i64;
    let end_pos = grid_pos + 4 + 4 + transform.len() as i64;
    for p in [grid_pos, end_pos, end_pos] {
        extra.extend_from_slice(&p.to_le_bytes());
    }
    extra.extend_from_slice(&compression);
    extra.extend_from_slice(&0i32.to_le_bytes());
    extra.extend_from_slice(&transform);
    data.extend_from_slice(&extra);

    let f = nimbus::vdb::read_bytes(&data, std::path::Path::new("instanced.vdb")).unwrap();
    assert_eq!(f.grids.len(), 2);
    assert_eq!(f.grids[1].name, "inst");
    assert_eq!(f.grids[1].instance_of.as_deref(), Some("density"));
    assert!(std::sync::Arc::ptr_eq(&f.grids[0].tree, &f.grids[1].tree));
    assert_eq!(f.grids[1].tree.stats().active_voxels, 17256);
    assert_eq!(f.grids[0].index_to_world, f.grids[1].index_to_world);
}

/// The cached accessor and its trilinear sampler agree with uncached lookups on real trees with tiles.
#[test]
fn accessor_agrees_with_tree_on_corpus() {
    let Some(dir) = common::vdb_corpus_dir() else {
        return;
    };
    for name in [
        "generated/h_tiles.vdb",
        "generated/j_root_tile.vdb",
        "real/elyg_pig.vdb",
    ] {
        let f = nimbus::vdb::read_file(&dir.join(name)).unwrap();
        let t = f.grids[0].tree.as_float().unwrap();
        let (lo, hi) = t.stats().bbox.unwrap();
        let (lo, hi) = (lo.max(IVec3::splat(-400)), hi.min(IVec3::splat(400)));
        let size = (hi - lo).as_vec3() + 40.0;
        let mut a = t.accessor();
        let mut seed = 7u64;
        for _ in 0..100_000 {
            let mut u = || {
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((seed >> 40) as f32) / (1u64 << 24) as f32
            };
            let x = lo.as_vec3() - 20.0 + glam::Vec3::new(u(), u(), u()) * size;
            let p = x.floor().as_ivec3();
            assert_eq!(a.value(p), t.value(p), "{name} at {p}");
            let s = a.sample_trilinear(x);
            let s2 = t.sample_trilinear(x);
            assert!((s - s2).abs() <= 1e-5 * s2.abs().max(1.0), "{name} at {x}");
        }
    }
}

/// `FileInfo` serialises to exactly the documented keys, and its table names every grid.
#[test]
fn info_json_keys_and_table() {
    let Some(dir) = common::vdb_corpus_dir() else {
        return;
    };
    let info = file_info(&dir.join("generated/g_vec3.vdb")).unwrap();
    let v = serde_json::to_value(&info).unwrap();
    let top: Vec<&str> = v.as_object().unwrap().keys().map(|k| k.as_str()).collect();
    assert_eq!(top.len(), 2);
    assert!(top.contains(&"file") && top.contains(&"grids"));
    let expected = [
        "name",
        "value_type",
        "class",
        "half",
        "active_voxels",
        "leaf_voxels",
        "tiles",
        "leaves",
        "sum",
        "min",
        "max",
        "bbox_min",
        "bbox_max",
        "voxel_size",
        "background",
        "index_to_world",
        "memory_bytes",
    ];
    for g in v["grids"].as_array().unwrap() {
        let mut keys: Vec<&str> = g.as_object().unwrap().keys().map(|k| k.as_str()).collect();
        keys.sort();
        let mut want = expected.to_vec();
        want.sort();
        assert_eq!(keys, want);
        assert_eq!(g["index_to_world"].as_array().unwrap().len(), 16);
    }
    assert!(
        v["grids"][1]["background"].is_array(),
        "vector background is an array"
    );
    let table = info.to_string();
    assert!(
        table.contains("density") && table.contains("vel"),
        "{table}"
    );
}

/// Region iteration over boxes (at the corners and the centre of the active bounding box, straddling its edges)
/// finds exactly the active voxels and values that a voxel-by-voxel scan finds, on corpus trees with tiles at
/// every level; and the whole tree's regions hold all its active voxels.
#[test]
fn regions_in_boxes_match_a_voxel_scan_on_corpus() {
    let Some(dir) = common::vdb_corpus_dir() else {
        return;
    };
    for name in [
        "generated/h_tiles.vdb",
        "generated/j_root_tile.vdb",
        "generated/a_sphere_fog.vdb",
        "real/elyg_pig.vdb",
    ] {
        let f = nimbus::vdb::read_file(&dir.join(name)).unwrap();
        let t = f.grids[0].tree.as_float().unwrap();
        let stats = t.stats();
        let (lo, hi) = stats.bbox.unwrap();
        let (lo, hi) = (lo.max(IVec3::splat(-5000)), hi.min(IVec3::splat(5000)));
        let mid = (lo + hi) / 2;
        let mut found = 0;
        for c in [lo, hi, mid, IVec3::new(lo.x, hi.y, mid.z)] {
            found += check_regions_in(t, c - 19, c + 20);
        }
        assert!(found > 0, "{name}: no active voxel in the boxes");
        assert_eq!(active_voxels_of_regions(t), stats.active_voxels, "{name}");
        eprintln!("ok {name}: {found} active voxels in the boxes");
    }
}

/// A glTF file placing grid `grid` of the corpus file `vdb` as a medium's density, loaded and built.
fn load_as_density(
    dir: &std::path::Path,
    vdb: &str,
    grid: &str,
) -> Result<nimbus::scene::Scene, String> {
    let folder = std::env::temp_dir().join(format!("nimbus-corpus-{grid}-{}", std::process::id()));
    std::fs::create_dir_all(&folder).unwrap();
    let gltf = folder.join("scene.gltf");
    let file = dir.join(vdb);
    std::fs::write(
        &gltf,
        format!(
            r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],
            "nodes":[{{"name":"v","extras":{{"nimbus_volume":{{"file":{:?},"density_grid":"{grid}"}}}}}}]}}"#,
            file.to_str().unwrap()
        ),
    )
    .unwrap();
    let scene = nimbus::scene::load_builder(&gltf, &nimbus::scene::LoadOptions::default())
        .and_then(|b| b.build())
        .map_err(|e| e.to_string());
    std::fs::remove_dir_all(&folder).ok();
    scene
}

/// A level set used as a density is refused with a message that says it is one (it used to say only that the
/// background was not zero). OpenVDB wrote `ls_sphere` with class "level set".
#[test]
fn a_level_set_is_refused_as_one() {
    let Some(dir) = common::vdb_corpus_dir() else {
        return;
    };
    let err = load_as_density(&dir, "generated/a2_levelset_sphere.vdb", "ls_sphere")
        .err()
        .expect("a level set is no density");
    assert!(
        err.contains("level set") && err.contains("fog volume") && err.contains("ls_sphere"),
        "{err}"
    );
}

/// The vec3 grid `vel` of `g_vec3.vdb` used as RGB density: OpenVDB's Python bindings count 57,856 active
/// voxels, all with a negative z component (and none negative in x or y). Those components are replaced by
/// zero, and the warning says how many, as it does for a scalar grid.
#[test]
fn negative_components_of_an_rgb_density_grid_warn_with_their_count() {
    let Some(dir) = common::vdb_corpus_dir() else {
        return;
    };
    let scene = load_as_density(&dir, "generated/g_vec3.vdb", "vel").unwrap();
    assert!(matches!(
        scene.media()[0].method().free_flight,
        nimbus::volume::FreeFlight::DeltaTracking {
            chromatic: Some(_),
            ..
        }
    ));
    assert!(
        scene
            .warnings()
            .iter()
            .any(|w| w.contains("0 NaN, 0 infinite and 57856 negative vec3 grid components")),
        "{:?}",
        scene.warnings()
    );
}
