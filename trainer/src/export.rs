//! Exports a checkpoint's actor for use outside this project: `policy.pt` (TorchScript,
//! raw observation in, action mean out, normalisation included; `torch.jit.load` loads
//! it), `policy.onnx` (the same function as an ONNX model, for onnxruntime and other
//! deployment runtimes), `policy.safetensors` (actor weights and normalisation) and `policy.json` (the
//! architecture, activation, observation scaling and how actions become joint targets).

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use tch::{Device, Kind, Tensor};

use crate::checkpoint::{write_safetensors, Checkpoint};
use crate::ppo::{Mlp, ObsNormalizer};
use crate::{Error, Result};

/// How the robot turns actions into joint targets (from its preset), for `policy.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ControlInfo {
    /// Joint names in action order.
    pub joints: Vec<String>,
    /// `target = default_pose + action_scale * action`.
    pub action_scale: f64,
    /// Default joint angles (rad) in action order.
    pub default_pose: Vec<f64>,
    /// Seconds between policy steps.
    pub policy_dt: f64,
}

/// The contents of `policy.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PolicyDescription {
    /// Robot preset name.
    pub robot: String,
    /// sha256 of the preset and its URDF.
    pub preset_digest: String,
    /// Terrain trained on.
    pub terrain: String,
    /// Velocity-tracking weight.
    pub w1: f64,
    /// Torque-penalty exponent.
    pub w2: f64,
    /// Epochs trained.
    pub epoch: u32,
    /// Layer sizes `[obs_dim, hidden..., act_dim]`.
    pub layers: Vec<i64>,
    /// Activation after every hidden layer (none after the output).
    pub activation: String,
    /// How raw observations are scaled before the first layer.
    pub obs_normalization: String,
    /// Per-dimension observation mean.
    pub obs_mean: Vec<f64>,
    /// Per-dimension observation variance.
    pub obs_var: Vec<f64>,
    /// Added to the standard deviation.
    pub obs_eps: f64,
    /// Normalised observations are clipped to +-this.
    pub obs_clip: f64,
    /// Tensor names in `policy.safetensors`.
    pub tensors: Vec<String>,
    /// Action to joint target mapping, when the preset was available.
    pub control: Option<ControlInfo>,
}

/// The files written by [`export`].
#[derive(Debug)]
pub struct Exported {
    /// TorchScript module.
    pub torchscript: PathBuf,
    /// The same function as an ONNX model.
    pub onnx: PathBuf,
    /// Actor weights and normalisation.
    pub safetensors: PathBuf,
    /// Description.
    pub json: PathBuf,
}

/// The actor and normalisation of a checkpoint, as a plain function of raw observations.
#[derive(Debug)]
pub struct ExportedActor {
    /// The actor MLP (no gradients).
    pub actor: Mlp,
    /// Observation mean `[obs_dim]` (f32).
    pub mean: Tensor,
    /// `sqrt(var) + eps` `[obs_dim]` (f32).
    pub denom: Tensor,
}

impl ExportedActor {
    /// Reads the actor of `ckpt`.
    pub fn from_checkpoint(ckpt: &Checkpoint) -> Result<Self> {
        let mut layers = Vec::new();
        for i in 0.. {
            let Ok(w) = ckpt.tensor(&format!("actor.{i}.weight")) else {
                break;
            };
            let b = ckpt.tensor(&format!("actor.{i}.bias"))?;
            layers.push((w.to_kind(Kind::Float), b.to_kind(Kind::Float)));
        }
        if layers.is_empty() {
            return Err(Error::checkpoint(&ckpt.path, "no actor layers"));
        }
        let normalizer = ObsNormalizer::from_tensors_f64(
            ckpt.tensor("obs_norm.mean")?,
            ckpt.tensor("obs_norm.var")?,
            ckpt.meta.normalizer.count,
        )?;
        let (mean, denom) = normalizer.tensors(Device::Cpu);
        Ok(Self {
            actor: Mlp { layers },
            mean,
            denom,
        })
    }

    /// Action means for raw observations `[B, obs_dim]`.
    pub fn forward(&self, obs: &Tensor) -> Tensor {
        self.actor
            .forward(&ObsNormalizer::apply(obs, &self.mean, &self.denom))
    }
}

/// Writes `policy.pt`, `policy.safetensors` and `policy.json` for `ckpt_path` into `out`.
pub fn export(ckpt_path: &Path, out: &Path, control: Option<ControlInfo>) -> Result<Exported> {
    let ckpt = Checkpoint::load(ckpt_path)?;
    let actor = ExportedActor::from_checkpoint(&ckpt)?;
    std::fs::create_dir_all(out).map_err(Error::io(format!("create {}", out.display())))?;
    let meta = &ckpt.meta;
    let obs_dim = actor.mean.size()[0];

    // Tracing records the weights as constants of the graph, so the module is standalone.
    let example = Tensor::zeros([1, obs_dim], (Kind::Float, Device::Cpu));
    let module = tch::no_grad(|| {
        tch::CModule::create_by_tracing("GaitPolicy", "forward", &[example], &mut |xs| {
            vec![actor.forward(&xs[0])]
        })
    })?;
    let torchscript = out.join("policy.pt");
    module.save(&torchscript)?;
    let onnx = out.join("policy.onnx");
    let doc = format!(
        "gaitsweep policy of {} on {} (w1 {}, w2 {}, epoch {}): raw observation in, action mean out",
        meta.robot, meta.terrain, meta.w1, meta.w2, meta.epoch
    );
    std::fs::write(&onnx, crate::onnx::actor_model(&actor, &doc)?)
        .map_err(Error::io(format!("write {}", onnx.display())))?;

    let mut tensors: Vec<(String, Tensor)> = Vec::new();
    for (i, (w, b)) in actor.actor.layers.iter().enumerate() {
        tensors.push((format!("actor.{i}.weight"), w.shallow_clone()));
        tensors.push((format!("actor.{i}.bias"), b.shallow_clone()));
    }
    let mean_f32 = Tensor::from_slice(&meta.normalizer.mean).to_kind(Kind::Float);
    let var_f32 = Tensor::from_slice(&meta.normalizer.var).to_kind(Kind::Float);
    tensors.push(("obs_mean".into(), mean_f32));
    tensors.push(("obs_var".into(), var_f32));
    let desc = PolicyDescription {
        robot: meta.robot.clone(),
        preset_digest: meta.preset_digest.clone(),
        terrain: meta.terrain.clone(),
        w1: meta.w1,
        w2: meta.w2,
        epoch: meta.epoch,
        layers: actor.actor.sizes(),
        activation: "elu".into(),
        obs_normalization:
            "x = clamp((obs - obs_mean) / (sqrt(obs_var) + obs_eps), -obs_clip, obs_clip)".into(),
        obs_mean: meta.normalizer.mean.clone(),
        obs_var: meta.normalizer.var.clone(),
        obs_eps: meta.normalizer.eps,
        obs_clip: meta.normalizer.clip,
        tensors: tensors.iter().map(|(n, _)| n.clone()).collect(),
        control,
    };
    let json = serde_json::to_string_pretty(&desc).expect("policy description serialises");
    let safetensors = out.join("policy.safetensors");
    write_safetensors(&safetensors, &tensors, &json)?;
    let json_path = out.join("policy.json");
    std::fs::write(&json_path, json + "\n")
        .map_err(Error::io(format!("write {}", json_path.display())))?;
    tracing::info!(checkpoint = %ckpt_path.display(), out = %out.display(), "exported policy");
    Ok(Exported {
        torchscript,
        onnx,
        safetensors,
        json: json_path,
    })
}
