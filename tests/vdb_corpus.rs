//! Reads every grid of the shared VDB corpus and compares it with what OpenVDB C++ reports (`truth.tsv`).

mod common;

use nimbus::vdb::{file_info, GridInfo};

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
        g.active_voxels,
        t[4].parse::<u64>().unwrap(),
        "{what}: active"
    );
    assert_eq!(
        g.leaf_voxels,
        t[5].parse::<u64>().unwrap(),
        "{what}: leaf voxels"
    );
    assert_eq!(g.tiles, t[6].parse::<u64>().unwrap(), "{what}: tiles");
    assert_eq!(g.leaves, t[7].parse::<u64>().unwrap(), "{what}: leaves");
    let sum: f64 = t[8].parse().unwrap();
    assert!(close(g.sum, sum, 1e-5), "{what}: sum {} vs {sum}", g.sum);
    let (mn, mx): (f64, f64) = (t[9].parse().unwrap(), t[10].parse().unwrap());
    assert!(close(g.min, mn, 1e-6), "{what}: min {} vs {mn}", g.min);
    assert!(close(g.max, mx, 1e-6), "{what}: max {} vs {mx}", g.max);
    assert_eq!(g.bbox_min, ivec(t[11]), "{what}: bbox min");
    assert_eq!(g.bbox_max, ivec(t[12]), "{what}: bbox max");
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
