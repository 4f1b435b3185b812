//! `worker train` writes TensorBoard scalars that TensorBoard itself reads back equal to
//! metrics.jsonl (the real binary, the real simulator and trainer, Python's `tensorboard`
//! package from the venv of scripts/setup.sh).

mod common;

use std::collections::BTreeMap;
use std::process::Command;

/// TensorBoard's own reader: every scalar as "tag step value" lines.
const READ: &str = r#"
import sys
from tensorboard.backend.event_processing.event_accumulator import EventAccumulator
acc = EventAccumulator(sys.argv[1], size_guidance={"scalars": 0})
acc.Reload()
for tag in acc.Tags()["scalars"]:
    for e in acc.Scalars(tag):
        print(tag, e.step, repr(e.value))
"#;

#[test]
fn worker_train_writes_tensorboard_scalars_equal_to_its_metrics() {
    let _heavy = common::heavy_blocking();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let status = Command::new(common::bin("worker"))
        .args([
            "train",
            "--robot",
            "anymal",
            "--terrain",
            "rough",
            "--w1",
            "7",
            "--w2",
            "-6",
        ])
        .args([
            "--agents",
            "8",
            "--epochs",
            "3",
            "--seed",
            "1",
            "--eval-every",
            "3",
        ])
        .args([
            "--eval-robots",
            "2",
            "--eval-seconds",
            "1",
            "--threads",
            "2",
            "--quiet",
        ])
        .arg("--out")
        .arg(&out)
        .status()
        .unwrap();
    assert!(status.success(), "worker train failed");

    let mut expected: BTreeMap<(String, u32), f64> = BTreeMap::new();
    for line in std::fs::read_to_string(out.join("metrics.jsonl"))
        .unwrap()
        .lines()
    {
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        let epoch = v["epoch"].as_u64().unwrap() as u32;
        for (k, x) in v["values"].as_object().unwrap() {
            expected.insert((k.clone(), epoch), x.as_f64().unwrap());
        }
    }
    for tag in [
        "reward/torques",
        "loss/value",
        "kl",
        "learning_rate",
        "action_std",
    ] {
        assert!(
            expected.contains_key(&(tag.to_string(), 3)),
            "metrics.jsonl lacks {tag}"
        );
    }
    assert!(expected.contains_key(&("eval/score".to_string(), 3)));
    assert!(expected.contains_key(&("curriculum/mean_level".to_string(), 1)));

    let read = Command::new(common::python())
        .args(["-c", READ])
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        read.status.success(),
        "tensorboard could not read {}: {}",
        out.display(),
        String::from_utf8_lossy(&read.stderr)
    );
    let mut got: BTreeMap<(String, u32), f64> = BTreeMap::new();
    for line in String::from_utf8_lossy(&read.stdout).lines() {
        let mut f = line.split(' ');
        let (tag, step, value) = (f.next().unwrap(), f.next().unwrap(), f.next().unwrap());
        got.insert((tag.into(), step.parse().unwrap()), value.parse().unwrap());
    }
    assert_eq!(
        got.keys().collect::<Vec<_>>(),
        expected.keys().collect::<Vec<_>>(),
        "tensorboard's tags and steps differ from metrics.jsonl's"
    );
    for (k, want) in &expected {
        // Scalars are stored as 32-bit floats.
        let have = got[k];
        assert!(
            (have - want).abs() <= 1e-6 * (1.0 + want.abs()),
            "{} at epoch {}: tensorboard {have}, metrics.jsonl {want}",
            k.0,
            k.1
        );
    }
}
