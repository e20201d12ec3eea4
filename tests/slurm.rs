//! The sharded bake on a real scheduler: `slurm/bake-shards.sh` submits the shards as a Slurm
//! array job and the merge as a job that depends on them, on the single-node cluster ci/test.sh
//! starts (ci/slurm/start-cluster.sh). The merged file must equal the single-process bake, also
//! after one shard is rerun alone. Without a cluster the test is skipped with the reason, except
//! under CI, where that is a failure.

mod common;

use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

use common::prt_gpu;

const BUNNY: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/bunny.obj");
const SUBMIT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/slurm/bake-shards.sh");
/// The bake both the Slurm jobs and the single process run.
const OPTIONS: [&str; 6] = [
    "--device",
    "cpu",
    "--samples",
    "64",
    "--mode",
    "interreflected",
];

/// Whether a Slurm cluster with a usable node answers; panics under CI when none does.
fn slurm_cluster_or_skip() -> bool {
    let states = Command::new("sinfo")
        .args(["--noheader", "-o", "%t"])
        .output();
    let usable = matches!(&states, Ok(out) if out.status.success()
        && String::from_utf8_lossy(&out.stdout)
            .lines()
            .any(|s| ["idle", "mix", "alloc"].contains(&s.trim())));
    if usable {
        return true;
    }
    let why = match states {
        Err(e) => format!("sinfo cannot run ({e}): Slurm is not installed"),
        Ok(out) => format!(
            "no usable Slurm node (sinfo: {}{})",
            String::from_utf8_lossy(&out.stdout).trim(),
            String::from_utf8_lossy(&out.stderr).trim()
        ),
    };
    if prt_gpu::device::adapter_required() {
        panic!("{why}, under CI (ci/test.sh starts a cluster with ci/slurm/start-cluster.sh)");
    }
    eprintln!("skipping the Slurm test: {why}");
    false
}

/// Submits `count` shards of a bake of the bunny (only `shards` of them, when given) and its
/// merge to `output` in `dir`; waits for both jobs and returns the merge job's final state.
fn submit_and_wait(dir: &Path, count: u32, shards: Option<&str>, output: &str) -> String {
    let mut submit = Command::new("bash");
    submit
        .arg(SUBMIT)
        .args([&count.to_string(), output, BUNNY])
        .args(OPTIONS)
        .env("PRT_GPU", env!("CARGO_BIN_EXE_prt-gpu"))
        .env("PARTS_DIR", dir.join("parts"))
        .current_dir(dir);
    if let Some(shards) = shards {
        submit.env("SHARDS", shards);
    }
    let out = submit.output().expect("run slurm/bake-shards.sh");
    assert!(
        out.status.success(),
        "submit: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let ids = String::from_utf8_lossy(&out.stdout).to_string();
    let ids: Vec<&str> = ids.split_whitespace().collect();
    assert_eq!(
        ids.len(),
        2,
        "the submit script prints two job ids: {ids:?}"
    );
    let started = Instant::now();
    while queued(ids[0]) || queued(ids[1]) {
        assert!(
            started.elapsed() < Duration::from_secs(300),
            "the Slurm jobs {ids:?} did not finish in 5 minutes"
        );
        std::thread::sleep(Duration::from_millis(500));
    }
    job_state(ids[1])
}

fn queued(job: &str) -> bool {
    let out = Command::new("squeue")
        .args(["--noheader", "-j", job])
        .output()
        .expect("run squeue");
    !String::from_utf8_lossy(&out.stdout).trim().is_empty()
}

fn job_state(job: &str) -> String {
    let out = Command::new("scontrol")
        .args(["show", "job", "-o", job])
        .output()
        .expect("run scontrol");
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    text.split_whitespace()
        .find_map(|field| field.strip_prefix("JobState="))
        .unwrap_or("unknown")
        .to_string()
}

fn logs(dir: &Path) -> String {
    let mut all = String::new();
    if let Ok(entries) = std::fs::read_dir(dir.join("parts/logs")) {
        for entry in entries.flatten() {
            all += &format!("{}:\n", entry.path().display());
            all += &std::fs::read_to_string(entry.path()).unwrap_or_default();
        }
    }
    all
}

#[test]
fn slurm_array_shards_merge_to_the_single_process_bake() {
    if !slurm_cluster_or_skip() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut single = vec!["bake", BUNNY, "-o", "single.glb"];
    single.extend(OPTIONS);
    let single = prt_gpu(&single, d);
    assert!(single.status.success());
    let single = std::fs::read(d.join("single.glb")).unwrap();

    let state = submit_and_wait(d, 3, None, "merged.glb");
    assert_eq!(state, "COMPLETED", "merge job: {}", logs(d));
    let merged = std::fs::read(d.join("merged.glb")).unwrap();
    assert!(
        merged == single,
        "the Slurm-merged file differs from the single bake"
    );

    // A lost shard is rerun alone, and the merge behind it gives the same bytes.
    std::fs::remove_file(d.join("parts/part-1-of-3.part")).unwrap();
    let state = submit_and_wait(d, 3, Some("1"), "remerged.glb");
    assert_eq!(state, "COMPLETED", "merge job after the rerun: {}", logs(d));
    let remerged = std::fs::read(d.join("remerged.glb")).unwrap();
    assert!(remerged == single, "the merge after a rerun differs");
}
