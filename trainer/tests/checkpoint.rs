//! Checkpoints: round trip, resume (the learner restored bit for bit, training continues),
//! refusal of torn and mismatched files, and the TorchScript export giving the live
//! actor's actions.

use std::path::Path;

use gaitsweep_trainer::checkpoint::{
    self, Checkpoint, CheckpointMeta, NormalizerMeta, OptimizerMeta, RngMeta,
};
use gaitsweep_trainer::export::{export, ExportedActor};
use gaitsweep_trainer::ppo::toy::PointMass;
use gaitsweep_trainer::ppo::{Ppo, PpoParams, Runner};
use tch::{Device, Kind, Tensor};

const EVERY: u32 = 3;

fn params() -> PpoParams {
    PpoParams {
        actor_hidden: vec![32, 16],
        critic_hidden: vec![32],
        steps_per_env: 10,
        ..PpoParams::default()
    }
}

fn meta(robot: &str) -> CheckpointMeta {
    CheckpointMeta {
        format: checkpoint::FORMAT_VERSION,
        robot: robot.into(),
        preset_digest: "toy-digest".into(),
        terrain: "flat".into(),
        difficulty: None,
        w1: 2.0,
        w2: -6.0,
        seed: 11,
        epoch: 0,
        agents: 32,
        obs_dim: 4,
        act_dim: 2,
        checkpoint_every: EVERY,
        ppo: params(),
        normalizer: NormalizerMeta {
            count: 0,
            mean: vec![],
            var: vec![],
            eps: 0.0,
            clip: 0.0,
        },
        optimizer: OptimizerMeta {
            kind: "adam".into(),
            learning_rate: 0.0,
            step: 0,
            betas: [0.0; 2],
            eps: 0.0,
        },
        rng: RngMeta {
            scheme: String::new(),
            resume_seed: 0,
        },
        levels: vec![],
        rewarded: false,
    }
}

fn fresh(p: PpoParams) -> Ppo {
    Ppo::new(4, 2, p, Device::Cpu, 11)
}

fn runner(ppo: Ppo, epoch: u32) -> Runner<PointMass> {
    Runner::new(
        PointMass::new(32, 11),
        ppo,
        11,
        epoch,
        "(w1=2, w2=-6)".into(),
    )
}

/// Every tensor of the learner's state, flattened, in checkpoint order.
fn state(ppo: &Ppo) -> Vec<(String, Vec<f32>)> {
    let mut out = Vec::new();
    for (((name, p), m), v) in ppo
        .model
        .named_parameters()
        .iter()
        .zip(&ppo.optim.m)
        .zip(&ppo.optim.v)
    {
        for (suffix, t) in [("", p), (".m", m), (".v", v)] {
            out.push((
                format!("{name}{suffix}"),
                Vec::<f32>::try_from(t.detach().flatten(0, -1)).unwrap(),
            ));
        }
    }
    out
}

fn save(dir: &Path, r: &Runner<PointMass>) -> std::path::PathBuf {
    let mut m = meta("toy");
    m.epoch = r.epoch;
    checkpoint::save(dir, &r.ppo, &m).unwrap()
}

#[test]
fn resumed_run_restores_the_learner_and_continues() {
    tch::set_num_threads(1);
    let dir = tempfile::tempdir().unwrap();
    let mut a = runner(fresh(params()), 0);
    let mut ckpt = None;
    let mut at_ckpt = None;
    for _ in 0..2 * EVERY {
        a.run_epoch().unwrap();
        if a.epoch == EVERY {
            ckpt = Some(save(dir.path(), &a));
            at_ckpt = Some((state(&a.ppo), a.ppo.normalizer.clone(), a.ppo.optim.step));
        }
    }
    let (want, want_norm, want_step) = at_ckpt.unwrap();
    let ckpt = Checkpoint::load(&ckpt.unwrap()).unwrap();
    assert_eq!(ckpt.meta.epoch, EVERY);
    ckpt.check_matches(&meta("toy")).unwrap();
    // A different initialisation proves that the restore, not the seed, gives the state.
    let mut ppo = Ppo::new(4, 2, params(), Device::Cpu, 999);
    ckpt.restore(&mut ppo).unwrap();
    assert_eq!(ppo.normalizer, want_norm);
    assert_eq!(ppo.optim.step, want_step);
    for ((name, x), (_, y)) in want.iter().zip(state(&ppo)) {
        let same = x.iter().zip(&y).all(|(p, q)| p.to_bits() == q.to_bits());
        assert!(same, "{name} differs after restore");
    }
    let mut b = runner(ppo, ckpt.meta.epoch);
    while b.epoch < 2 * EVERY {
        b.run_epoch().unwrap();
    }
    assert_eq!(b.ppo.optim.step, a.ppo.optim.step);
    // The resumed robots start new episodes: their first observations are counted too.
    assert!(b.ppo.normalizer.count > want_norm.count);
}

#[test]
fn checkpoint_round_trip_and_sidecar() {
    let dir = tempfile::tempdir().unwrap();
    let mut r = runner(fresh(params()), 0);
    r.run_epoch().unwrap();
    let path = save(dir.path(), &r);
    assert_eq!(path.file_name().unwrap(), "ckpt-000001.safetensors");
    let sidecar: CheckpointMeta =
        serde_json::from_str(&std::fs::read_to_string(path.with_extension("json")).unwrap())
            .unwrap();
    let ckpt = Checkpoint::load(&path).unwrap();
    assert_eq!(sidecar, ckpt.meta, "sidecar and embedded metadata differ");
    assert_eq!(ckpt.meta.normalizer.count, r.ppo.normalizer.count);
    let mut back = fresh(params());
    ckpt.restore(&mut back).unwrap();
    assert_eq!(state(&back), state(&r.ppo));
    assert_eq!(back.normalizer, r.ppo.normalizer);

    // A checkpoint written before `rewarded` was recorded reads as rewarded: a resumed run
    // is never stopped as unrewarded on a guess.
    let mut old = serde_json::to_value(&ckpt.meta).unwrap();
    old.as_object_mut().unwrap().remove("rewarded");
    let old: CheckpointMeta = serde_json::from_value(old).unwrap();
    assert!(old.rewarded);
}

#[test]
fn torn_and_mismatched_checkpoints_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let r = runner(fresh(params()), 0);
    let path = save(dir.path(), &r);
    let bytes = std::fs::read(&path).unwrap();

    let torn = dir.path().join("torn.safetensors");
    std::fs::write(&torn, &bytes[..bytes.len() - 100]).unwrap();
    let e = Checkpoint::load(&torn).unwrap_err().to_string();
    assert!(
        e.contains("torn.safetensors") && e.contains("not a whole"),
        "{e}"
    );

    let ckpt = Checkpoint::load(&path).unwrap();
    let e = ckpt.check_matches(&meta("heavy")).unwrap_err().to_string();
    assert!(
        e.contains("ckpt-000000") && e.contains("robot is toy but this run has heavy"),
        "{e}"
    );
    let mut other = meta("toy");
    other.preset_digest = "changed".into();
    let e = ckpt.check_matches(&other).unwrap_err().to_string();
    assert!(e.contains("preset digest"), "{e}");
    other = meta("toy");
    other.w2 = -4.0;
    let e = ckpt.check_matches(&other).unwrap_err().to_string();
    assert!(
        e.contains("cell is (w1=2, w2=-6) but this run has (w1=2, w2=-4)"),
        "{e}"
    );

    let mut wider = fresh(PpoParams {
        actor_hidden: vec![64, 16],
        ..params()
    });
    let e = ckpt.restore(&mut wider).unwrap_err().to_string();
    assert!(
        e.contains("tensor actor.0.weight has shape [32, 4] but this run expects [64, 4]"),
        "{e}"
    );
}

#[test]
fn torchscript_export_matches_live_actor() {
    let dir = tempfile::tempdir().unwrap();
    let mut r = runner(fresh(params()), 0);
    r.run_epoch().unwrap();
    let path = save(dir.path(), &r);
    let out = dir.path().join("export");
    let files = export(&path, &out, None).unwrap();

    let obs = Tensor::randn([64, 4], (Kind::Float, Device::Cpu)) * 2.0;
    let obs_host = Vec::<f32>::try_from(obs.flatten(0, -1)).unwrap();
    let mut live = vec![0.0f32; 64 * 2];
    r.ppo.act_deterministic(&obs_host, &mut live).unwrap();

    let module = tch::CModule::load(&files.torchscript).unwrap();
    let traced = Vec::<f32>::try_from(module.forward_ts(&[&obs]).unwrap().flatten(0, -1)).unwrap();
    let ckpt = Checkpoint::load(&path).unwrap();
    let plain = ExportedActor::from_checkpoint(&ckpt).unwrap();
    let plain = Vec::<f32>::try_from(tch::no_grad(|| plain.forward(&obs)).flatten(0, -1)).unwrap();
    for ((l, t), p) in live.iter().zip(&traced).zip(&plain) {
        assert!(
            (l - t).abs() <= 1e-5 * (1.0 + l.abs()),
            "torchscript {t} vs live {l}"
        );
        assert!(
            (l - p).abs() <= 1e-5 * (1.0 + l.abs()),
            "safetensors actor {p} vs live {l}"
        );
    }
    let desc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&files.json).unwrap()).unwrap();
    assert_eq!(desc["layers"], serde_json::json!([4, 32, 16, 2]));
    assert_eq!(desc["activation"], "elu");

    // Python's torch.jit.load must load it too (the venv that scripts/setup.sh installs).
    let python = venv_python();
    let script = "import sys, torch; m = torch.jit.load(sys.argv[1]); \
                  print(' '.join(repr(v) for v in m(torch.full((1, 4), 0.5)).flatten().tolist()))";
    let out = std::process::Command::new(python)
        .args(["-c", script])
        .arg(&files.torchscript)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "torch.jit.load failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let py: Vec<f32> = String::from_utf8_lossy(&out.stdout)
        .split_whitespace()
        .map(|v| v.parse().unwrap())
        .collect();
    let x = Tensor::full([1, 4], 0.5, (Kind::Float, Device::Cpu));
    let rs = Vec::<f32>::try_from(module.forward_ts(&[&x]).unwrap().flatten(0, -1)).unwrap();
    assert_eq!(py.len(), 2);
    for (a, b) in py.iter().zip(&rs) {
        assert!((a - b).abs() <= 1e-5, "python {a} vs tch {b}");
    }
}

/// `policy.onnx` computes what the Rust policy does: Python's onnxruntime and torch (the
/// venv `scripts/setup.sh` installs) run the ONNX model and the TorchScript module on the
/// same observations, some far enough out to hit the normaliser's clip, and both agree
/// with the live actor within 1e-5.
#[test]
fn onnx_export_matches_the_rust_policy_in_onnxruntime_and_torch() {
    let dir = tempfile::tempdir().unwrap();
    let mut r = runner(fresh(params()), 0);
    r.run_epoch().unwrap();
    let path = save(dir.path(), &r);
    let files = export(&path, &dir.path().join("export"), None).unwrap();
    assert!(files.onnx.is_file());

    let n = 64;
    let obs = Tensor::randn([n, 4], (Kind::Float, Device::Cpu)) * 30.0;
    let obs_host = Vec::<f32>::try_from(obs.flatten(0, -1)).unwrap();
    let mut live = vec![0.0f32; n as usize * 2];
    r.ppo.act_deterministic(&obs_host, &mut live).unwrap();
    let obs_file = dir.path().join("obs.f32");
    std::fs::write(
        &obs_file,
        obs_host
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect::<Vec<u8>>(),
    )
    .unwrap();

    let python = venv_python();
    let script = "import sys, numpy as np, onnxruntime as ort, torch\n\
                  obs = np.fromfile(sys.argv[3], dtype='<f4').reshape(-1, 4)\n\
                  s = ort.InferenceSession(sys.argv[1], providers=['CPUExecutionProvider'])\n\
                  a = s.run(['actions'], {'obs': obs})[0]\n\
                  t = torch.jit.load(sys.argv[2])(torch.from_numpy(obs)).detach().numpy()\n\
                  print(' '.join(repr(float(v)) for v in a.flatten()))\n\
                  print(' '.join(repr(float(v)) for v in t.flatten()))\n";
    let out = std::process::Command::new(python)
        .args(["-c", script])
        .arg(&files.onnx)
        .arg(&files.torchscript)
        .arg(&obs_file)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "onnxruntime or torch failed on the export: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    let rows: Vec<Vec<f32>> = text
        .lines()
        .map(|l| l.split_whitespace().map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 2, "{text}");
    for (name, row) in ["onnxruntime", "torch"].iter().zip(&rows) {
        assert_eq!(row.len(), live.len(), "{name}");
        let worst = row
            .iter()
            .zip(&live)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        assert!(
            worst <= 1e-5,
            "{name} differs from the Rust policy by up to {worst}"
        );
    }
}

/// The python of the venv `scripts/setup.sh` installs (torch, onnxruntime).
fn venv_python() -> std::path::PathBuf {
    std::env::var_os("GAITSWEEP_CACHE")
        .map(std::path::PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| Path::new(&h).join(".cache/gaitsweep")))
        .map(|c| c.join("venv/bin/python"))
        .filter(|p| p.exists())
        .expect("the venv of scripts/setup.sh (torch, onnxruntime) is missing: run the tests through scripts/test.sh")
}
