//! Batch bakes: many meshes in one process and one device, each written as its own bake would
//! be; a broken mesh is reported and skipped, and the exit says so at the end.

mod common;

use common::prt_gpu;

const DATA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data");

#[test]
fn a_batch_bakes_each_mesh_as_alone_and_skips_a_broken_one() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let meshes = d.join("meshes");
    std::fs::create_dir(&meshes).unwrap();
    std::fs::copy(format!("{DATA}/teapot.obj"), meshes.join("teapot.obj")).unwrap();
    std::fs::write(meshes.join("broken.obj"), "v 1 2\nf 1 2 3\n").unwrap();
    std::fs::write(meshes.join("readme.txt"), "not a mesh").unwrap();
    let bunny = format!("{DATA}/bunny.obj");
    let box_glb = format!("{DATA}/gltf/BoxTextured.glb");
    let options = ["--device", "cpu", "--samples", "64"];
    let mut args = vec!["bake", &bunny, "meshes", &box_glb, "--out-dir", "baked"];
    args.extend(options);
    let out = prt_gpu(&args, d);
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(!out.status.success(), "a batch with a broken mesh exits 0");
    assert!(stderr.contains("broken.obj"), "{stderr}");
    assert!(stderr.contains("batch: 1 of 4 meshes failed"), "{stderr}");
    assert_eq!(
        stdout.lines().filter(|l| l.starts_with("baked ")).count(),
        3,
        "{stdout}"
    );
    assert!(stdout.contains("batch: 3 of 4 meshes baked"), "{stdout}");
    let mut written = prt_gpu::testing::entries(&d.join("baked"));
    written.sort();
    assert_eq!(
        written,
        ["BoxTextured.prt.glb", "bunny.prt.glb", "teapot.prt.glb"]
    );

    // Each equals the bake of that mesh alone.
    for (mesh, baked) in [
        (bunny.as_str(), "bunny.prt.glb"),
        ("meshes/teapot.obj", "teapot.prt.glb"),
        (box_glb.as_str(), "BoxTextured.prt.glb"),
    ] {
        let mut alone = vec!["bake", mesh, "-o", "alone.glb"];
        alone.extend(options);
        assert!(prt_gpu(&alone, d).status.success());
        let same = std::fs::read(d.join("alone.glb")).unwrap()
            == std::fs::read(d.join("baked").join(baked)).unwrap();
        assert!(same, "{baked} differs from the bake of {mesh} alone");
    }
}

/// Local lights bake in batches too: one device, and each file the bake of its mesh alone.
#[test]
fn a_local_lights_batch_bakes_each_mesh_as_alone() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (bunny, teapot) = (format!("{DATA}/bunny.obj"), format!("{DATA}/teapot.obj"));
    // Small: the operator's clusters need no more receivers than these meshes have.
    let options = [
        "--mode",
        "local",
        "--device",
        "cpu",
        "--samples",
        "32",
        "--bounces",
        "1",
        "--depth-grid",
        "4",
        "--depth-compress",
        "8x2",
        "--operator-compress",
        "8x4",
        "--example-lights",
        "16",
    ];
    let mut args = vec!["bake", &bunny, &teapot, "--out-dir", "baked"];
    args.extend(options);
    let out = prt_gpu(&args, d);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        stdout
            .lines()
            .filter(|l| l.starts_with("baked ") && l.contains("for local lights"))
            .count(),
        2,
        "{stdout}"
    );
    assert!(stdout.contains("batch: 2 of 2 meshes baked"), "{stdout}");
    for (mesh, baked) in [(&bunny, "bunny.prt.glb"), (&teapot, "teapot.prt.glb")] {
        let batched = d.join("baked").join(baked);
        let read = prt_gpu::glb::local::read_local_glb(&batched).unwrap();
        assert!(read.scene.positions.len() > 100, "{baked}");
        let mut alone = vec!["bake", mesh.as_str(), "-o", "alone.glb"];
        alone.extend(options);
        assert!(prt_gpu(&alone, d).status.success());
        let same = std::fs::read(d.join("alone.glb")).unwrap() == std::fs::read(&batched).unwrap();
        assert!(
            same,
            "{baked} differs from the local-lights bake of {mesh} alone"
        );
    }
}

#[test]
fn batches_refuse_what_cannot_work_before_baking() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let bunny = format!("{DATA}/bunny.obj");
    std::fs::create_dir(d.join("other")).unwrap();
    std::fs::copy(&bunny, d.join("other/bunny.obj")).unwrap();
    std::fs::create_dir(d.join("empty")).unwrap();
    let cases: [(&[&str], &str); 5] = [
        (
            &["bake", &bunny, "other/bunny.obj", "--out-dir", "out"],
            "would both be baked to",
        ),
        (
            &["bake", &bunny, "other", "-o", "x.glb"],
            "-o names one output",
        ),
        (
            &["bake", "empty", "--out-dir", "out"],
            "holds no mesh files",
        ),
        (
            &["bake", "other/*.ply", "--out-dir", "out"],
            "holds no mesh files",
        ),
        (
            &["bake", &bunny, "other", "--shard", "0/2"],
            "--shard bakes one mesh",
        ),
    ];
    for (args, expected) in cases {
        let out = prt_gpu(args, d);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} succeeded");
        assert_eq!(stderr.trim().lines().count(), 1, "{args:?}: {stderr}");
        assert!(stderr.contains(expected), "{args:?}: {stderr}");
        assert!(!d.join("out").exists(), "{args:?} wrote output");
    }
}
