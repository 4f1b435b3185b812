//! One self-contained file per checkpoint: `ckpt-000100.safetensors` holds every tensor
//! (actor, critic, log-std, normaliser statistics, Adam moments and learning rate) and the
//! run's description as JSON in its `__metadata__`; `ckpt-000100.json` beside it repeats
//! that JSON for humans. Loading checks the file is whole, from the same robot, preset
//! and cell, and that every tensor has the shape this run expects.

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

use safetensors::tensor::{Dtype, SafeTensors, TensorView};
use serde::{Deserialize, Serialize};
use tch::{Device, Kind, Tensor};

use crate::ppo::{ObsNormalizer, Ppo, PpoParams};
use crate::{Error, Result};

/// Key of the run description in the safetensors `__metadata__`.
pub const METADATA_KEY: &str = "gaitsweep";
/// Version of the checkpoint layout.
pub const FORMAT_VERSION: u32 = 1;

/// File name of the checkpoint after `epoch` epochs.
pub fn checkpoint_name(epoch: u32) -> String {
    format!("ckpt-{epoch:06}.safetensors")
}

/// Observation normalisation as recorded in the sidecar (the exact values are tensors).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct NormalizerMeta {
    /// Observations folded in.
    pub count: u64,
    /// Per-dimension mean.
    pub mean: Vec<f64>,
    /// Per-dimension variance.
    pub var: Vec<f64>,
    /// `x_norm = clamp((x - mean) / (sqrt(var) + eps), -clip, clip)`.
    pub eps: f64,
    /// See `eps`.
    pub clip: f64,
}

/// Optimiser hyperstate (the moments are tensors `adam.m.*`, `adam.v.*`).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct OptimizerMeta {
    /// Always "adam".
    pub kind: String,
    /// Learning rate at the checkpoint (exact value: tensor `adam.lr`).
    pub learning_rate: f64,
    /// Adam steps taken.
    pub step: u64,
    /// Adam betas.
    pub betas: [f64; 2],
    /// Adam epsilon.
    pub eps: f64,
}

/// Random state: every checkpoint boundary reseeds the simulation and the trainer's own
/// generator (action noise, mini-batch order) from `boundary_seed(seed, epoch)`, so the
/// state is that seed.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct RngMeta {
    /// How the state is derived.
    pub scheme: String,
    /// Seed of the simulation reset and the trainer's generator when resuming here.
    pub resume_seed: u64,
}

/// The run description stored in every checkpoint.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct CheckpointMeta {
    /// Layout version, [`FORMAT_VERSION`].
    pub format: u32,
    /// Robot preset name.
    pub robot: String,
    /// sha256 of the preset and its URDF.
    pub preset_digest: String,
    /// Terrain ("flat", "rough", ...).
    pub terrain: String,
    /// Fixed difficulty, or None for the curriculum.
    pub difficulty: Option<u8>,
    /// Velocity-tracking weight.
    pub w1: f64,
    /// Torque-penalty exponent.
    pub w2: f64,
    /// The run's seed.
    pub seed: u64,
    /// Epochs completed.
    pub epoch: u32,
    /// Robots trained together.
    pub agents: usize,
    /// Observation length.
    pub obs_dim: usize,
    /// Action length.
    pub act_dim: usize,
    /// Epochs between checkpoint boundaries (reseeds).
    pub checkpoint_every: u32,
    /// PPO hyperparameters in force (preset plus overrides).
    pub ppo: PpoParams,
    /// Observation normalisation.
    pub normalizer: NormalizerMeta,
    /// Optimiser hyperstate.
    pub optimizer: OptimizerMeta,
    /// Random state.
    pub rng: RngMeta,
    /// Per-robot curriculum levels at the checkpoint (empty with a fixed difficulty).
    #[serde(default)]
    pub levels: Vec<u8>,
    /// Whether any epoch up to the checkpoint had a mean reward other than 0. Checkpoints
    /// written before it was recorded read as true: unknown counts as rewarded, so a
    /// resumed run is never stopped as unrewarded on a guess.
    #[serde(default = "rewarded_unknown")]
    pub rewarded: bool,
}

fn rewarded_unknown() -> bool {
    true
}

/// A checkpoint read from disk and checked to be whole.
#[derive(Debug)]
pub struct Checkpoint {
    /// The file it came from.
    pub path: PathBuf,
    /// Its run description.
    pub meta: CheckpointMeta,
    tensors: BTreeMap<String, Tensor>,
}

fn to_bytes(t: &Tensor) -> Result<(Dtype, Vec<usize>, Vec<u8>)> {
    let t = t.detach().to_device(Device::Cpu).contiguous();
    let shape = t.size().iter().map(|&d| d as usize).collect();
    let flat = t.flatten(0, -1);
    Ok(match t.kind() {
        Kind::Double => {
            let v = Vec::<f64>::try_from(&flat)?;
            (
                Dtype::F64,
                shape,
                v.iter().flat_map(|x| x.to_le_bytes()).collect(),
            )
        }
        _ => {
            let v = Vec::<f32>::try_from(&flat.to_kind(Kind::Float))?;
            (
                Dtype::F32,
                shape,
                v.iter().flat_map(|x| x.to_le_bytes()).collect(),
            )
        }
    })
}

/// Writes `tensors` and `json` (stored under [`METADATA_KEY`]) as one safetensors file,
/// through a temporary file and a rename so that a crash never leaves a torn file.
pub fn write_safetensors(path: &Path, tensors: &[(String, Tensor)], json: &str) -> Result<()> {
    let bufs = tensors
        .iter()
        .map(|(name, t)| Ok((name.clone(), to_bytes(t)?)))
        .collect::<Result<Vec<_>>>()?;
    let views = bufs
        .iter()
        .map(|(name, (dtype, shape, data))| {
            TensorView::new(*dtype, shape.clone(), data)
                .map(|v| (name.clone(), v))
                .map_err(|e| Error::checkpoint(path, e.to_string()))
        })
        .collect::<Result<Vec<_>>>()?;
    let meta = HashMap::from([
        (METADATA_KEY.to_string(), json.to_string()),
        ("format".to_string(), "pt".to_string()),
    ]);
    let tmp = path.with_extension("safetensors.tmp");
    safetensors::serialize_to_file(views, Some(meta), &tmp)
        .map_err(|e| Error::checkpoint(path, e.to_string()))?;
    std::fs::rename(&tmp, path).map_err(Error::io(format!("rename {}", tmp.display())))
}

/// Reads every tensor and the [`METADATA_KEY`] JSON of a safetensors file.
pub fn read_safetensors(path: &Path) -> Result<(BTreeMap<String, Tensor>, Option<String>)> {
    let buf = std::fs::read(path).map_err(Error::io(format!("read {}", path.display())))?;
    let st = SafeTensors::deserialize(&buf)
        .map_err(|e| Error::checkpoint(path, format!("not a whole safetensors file ({e})")))?;
    let (_, header) = SafeTensors::read_metadata(&buf)
        .map_err(|e| Error::checkpoint(path, format!("unreadable header ({e})")))?;
    let json = header
        .metadata()
        .as_ref()
        .and_then(|m| m.get(METADATA_KEY).cloned());
    let mut tensors = BTreeMap::new();
    for (name, view) in st.tensors() {
        let kind = match view.dtype() {
            Dtype::F32 => Kind::Float,
            Dtype::F64 => Kind::Double,
            other => {
                return Err(Error::checkpoint(
                    path,
                    format!("tensor {name} has dtype {other:?}"),
                ))
            }
        };
        let size: Vec<i64> = view.shape().iter().map(|&d| d as i64).collect();
        tensors.insert(name, Tensor::f_from_data_size(view.data(), &size, kind)?);
    }
    Ok((tensors, json))
}

/// Every tensor of `ppo`'s state with its checkpoint name.
fn state_tensors(ppo: &Ppo) -> Vec<(String, Tensor)> {
    let named = ppo.model.named_parameters();
    let mut out: Vec<(String, Tensor)> =
        named.iter().map(|(n, t)| (n.clone(), t.detach())).collect();
    let (mean, var) = ppo.normalizer.to_tensors_f64();
    out.push(("obs_norm.mean".into(), mean));
    out.push(("obs_norm.var".into(), var));
    for (((name, _), m), v) in named.iter().zip(&ppo.optim.m).zip(&ppo.optim.v) {
        out.push((format!("adam.m.{name}"), m.detach()));
        out.push((format!("adam.v.{name}"), v.detach()));
    }
    out.push(("adam.lr".into(), Tensor::from_slice(&[ppo.optim.lr])));
    out
}

/// Fills the normaliser and optimiser parts of `meta` from `ppo`.
pub fn describe_state(ppo: &Ppo, meta: &mut CheckpointMeta) {
    meta.normalizer = NormalizerMeta {
        count: ppo.normalizer.count,
        mean: ppo.normalizer.mean.clone(),
        var: ppo.normalizer.var.clone(),
        eps: crate::ppo::NORM_EPS,
        clip: crate::ppo::NORM_CLIP,
    };
    meta.optimizer = OptimizerMeta {
        kind: "adam".into(),
        learning_rate: ppo.optim.lr,
        step: ppo.optim.step,
        betas: [crate::ppo::adam::BETA1, crate::ppo::adam::BETA2],
        eps: crate::ppo::adam::EPS,
    };
    meta.ppo = ppo.params.clone();
}

/// Saves `ppo` with `meta` (its state fields refreshed) as `dir/ckpt-NNNNNN.safetensors`
/// plus the `.json` sidecar; returns the safetensors path.
pub fn save(dir: &Path, ppo: &Ppo, meta: &CheckpointMeta) -> Result<PathBuf> {
    let mut meta = meta.clone();
    describe_state(ppo, &mut meta);
    let path = dir.join(checkpoint_name(meta.epoch));
    let json = serde_json::to_string_pretty(&meta).expect("checkpoint meta serialises");
    write_safetensors(&path, &state_tensors(ppo), &json)?;
    let sidecar = path.with_extension("json");
    std::fs::write(&sidecar, json + "\n")
        .map_err(Error::io(format!("write {}", sidecar.display())))?;
    Ok(path)
}

impl Checkpoint {
    /// Reads a checkpoint; refuses a torn file or one without a run description.
    pub fn load(path: &Path) -> Result<Self> {
        let (tensors, json) = read_safetensors(path)?;
        let json = json.ok_or_else(|| {
            Error::checkpoint(path, format!("no `{METADATA_KEY}` entry in __metadata__"))
        })?;
        let meta: CheckpointMeta = serde_json::from_str(&json)
            .map_err(|e| Error::checkpoint(path, format!("bad run description ({e})")))?;
        if meta.format != FORMAT_VERSION {
            return Err(Error::checkpoint(
                path,
                format!(
                    "format {} but this worker reads {FORMAT_VERSION}",
                    meta.format
                ),
            ));
        }
        Ok(Self {
            path: path.to_path_buf(),
            meta,
            tensors,
        })
    }

    /// Refuses the checkpoint unless it comes from the same robot, preset and cell.
    pub fn check_matches(&self, want: &CheckpointMeta) -> Result<()> {
        let (have, path) = (&self.meta, &self.path);
        let mismatch = |what: &str, h: String, w: String| {
            Err(Error::checkpoint(
                path,
                format!("{what} is {h} but this run has {w}"),
            ))
        };
        if have.robot != want.robot {
            return mismatch("robot", have.robot.clone(), want.robot.clone());
        }
        if have.preset_digest != want.preset_digest {
            return mismatch(
                "preset digest",
                have.preset_digest.clone(),
                want.preset_digest.clone(),
            );
        }
        if have.terrain != want.terrain || have.difficulty != want.difficulty {
            return mismatch(
                "terrain",
                format!("{} {:?}", have.terrain, have.difficulty),
                format!("{} {:?}", want.terrain, want.difficulty),
            );
        }
        if have.w1 != want.w1 || have.w2 != want.w2 {
            return mismatch(
                "cell",
                format!("(w1={}, w2={})", have.w1, have.w2),
                format!("(w1={}, w2={})", want.w1, want.w2),
            );
        }
        if have.agents != want.agents {
            return mismatch("agents", have.agents.to_string(), want.agents.to_string());
        }
        if (have.obs_dim, have.act_dim) != (want.obs_dim, want.act_dim) {
            return mismatch(
                "obs/act dims",
                format!("{}/{}", have.obs_dim, have.act_dim),
                format!("{}/{}", want.obs_dim, want.act_dim),
            );
        }
        Ok(())
    }

    fn take(&self, name: &str, like: &Tensor) -> Result<&Tensor> {
        let t = self
            .tensors
            .get(name)
            .ok_or_else(|| Error::checkpoint(&self.path, format!("missing tensor {name}")))?;
        if t.size() != like.size() {
            return Err(Error::checkpoint(
                &self.path,
                format!(
                    "tensor {name} has shape {:?} but this run expects {:?}",
                    t.size(),
                    like.size()
                ),
            ));
        }
        Ok(t)
    }

    /// Copies weights, normaliser and optimiser state into `ppo` (built with the same
    /// architecture), checking every shape first so that a refusal changes nothing.
    pub fn restore(&self, ppo: &mut Ppo) -> Result<()> {
        let named = ppo.model.named_parameters();
        let mut pairs = Vec::new();
        for (((name, p), m), v) in named.iter().zip(&ppo.optim.m).zip(&ppo.optim.v) {
            pairs.push((p.shallow_clone(), self.take(name, p)?.shallow_clone()));
            pairs.push((
                m.shallow_clone(),
                self.take(&format!("adam.m.{name}"), m)?.shallow_clone(),
            ));
            pairs.push((
                v.shallow_clone(),
                self.take(&format!("adam.v.{name}"), v)?.shallow_clone(),
            ));
        }
        let (mean, var) = ppo.normalizer.to_tensors_f64();
        let mean = self.take("obs_norm.mean", &mean)?;
        let var = self.take("obs_norm.var", &var)?;
        let lr = self.take("adam.lr", &Tensor::from_slice(&[0.0f64]))?;
        tch::no_grad(|| {
            for (mut dst, src) in pairs {
                dst.copy_(&src);
            }
        });
        ppo.normalizer = ObsNormalizer::from_tensors_f64(mean, var, self.meta.normalizer.count)?;
        ppo.optim.lr = lr.double_value(&[0]);
        ppo.optim.step = self.meta.optimizer.step;
        Ok(())
    }

    /// A tensor by name (export reads weights through this).
    pub fn tensor(&self, name: &str) -> Result<&Tensor> {
        self.tensors
            .get(name)
            .ok_or_else(|| Error::checkpoint(&self.path, format!("missing tensor {name}")))
    }
}
