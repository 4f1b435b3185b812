//! Robot presets: `robots/<name>/preset.toml` plus the URDF it names.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::error::{Error, Result};

/// Where robot presets live: `$GAITSWEEP_ROBOTS` if set, else the `robots/` directory of the
/// source tree this crate was built from.
pub fn robots_dir() -> PathBuf {
    std::env::var_os("GAITSWEEP_ROBOTS")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../robots"))
}

/// PD control and physics settings of a robot.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ControlConfig {
    /// Joint stiffness Kp (N·m/rad).
    pub stiffness: f32,
    /// Joint damping Kd (N·m·s/rad).
    pub damping: f32,
    /// Torque limit per joint (N·m), also the score's `tau_max`.
    pub torque_limit: f32,
    /// Joint target = default + action_scale * action.
    pub action_scale: f32,
    /// Physics time step (s).
    pub sim_dt: f32,
    /// Physics steps per policy step.
    pub decimation: usize,
    /// rapier solver iterations per physics step.
    pub solver_iterations: usize,
    /// How joints are simulated: `multibody` or `impulse`.
    #[serde(default = "default_backend")]
    pub joints: crate::robot::JointBackend,
    /// rapier's internal PGS iterations per solver iteration (cheap: no mass matrix rebuild).
    #[serde(default = "one")]
    pub pgs_iterations: usize,
    /// Friction coefficient of feet and terrain.
    pub friction: f32,
    /// Leg cylinders of the URDF collide as capsules of the same radius and length
    /// (legged_gym's `replace_cylinder_with_capsule`, default true).
    #[serde(default = "yes")]
    pub capsule_legs: bool,
    /// Thigh and shank shapes collide with the terrain (default true; false leaves only
    /// the base and the feet, for measuring what the leg contacts cost).
    #[serde(default = "yes")]
    pub leg_collisions: bool,
    /// Clamp each joint's PD target to the joint's URDF limits (default false: legged_gym
    /// does not, and a policy may then press a joint into its stop at full torque).
    #[serde(default)]
    pub clamp_targets: bool,
    /// Episode length (s) during training.
    pub episode_seconds: f32,
}

fn default_backend() -> crate::robot::JointBackend {
    crate::robot::JointBackend::Multibody
}

fn one() -> usize {
    1
}

fn yes() -> bool {
    true
}

/// Observation layout and scaling (legged_gym's).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ObservationConfig {
    /// Scale of the base linear velocity.
    pub lin_vel_scale: f32,
    /// Scale of the base angular velocity.
    pub ang_vel_scale: f32,
    /// Scale of the joint positions (relative to the default pose).
    pub dof_pos_scale: f32,
    /// Scale of the joint velocities.
    pub dof_vel_scale: f32,
    /// Scale of the height scan.
    pub height_scale: f32,
    /// Observations are clipped to [-clip, clip].
    pub clip: f32,
    /// Height scan points along the base's forward axis (m).
    pub scan_x: Vec<f32>,
    /// Height scan points along the base's lateral axis (m).
    pub scan_y: Vec<f32>,
}

/// Command ranges (paper: forward speed and heading).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CommandConfig {
    /// Forward speed range (m/s).
    pub forward_speed: [f32; 2],
    /// Heading range (rad).
    pub heading: [f32; 2],
    /// Yaw rate command = clip(heading_gain * heading error, ±max_yaw_rate).
    pub heading_gain: f32,
    /// Largest commanded yaw rate (rad/s).
    pub max_yaw_rate: f32,
    /// Commands are resampled this often (s).
    pub resample_seconds: f32,
}

/// Fixed reward weights (everything but w1 and w2).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RewardConfig {
    /// Tracking kernel width: exp(-err² / sigma).
    pub tracking_sigma: f32,
    /// w3: heading (yaw rate) tracking.
    pub w3_heading: f32,
    /// w4: joint acceleration penalty.
    pub w4_dof_acc: f32,
    /// Vertical base velocity penalty.
    pub lin_vel_z: f32,
    /// Roll/pitch rate penalty.
    pub ang_vel_xy: f32,
    /// Action rate penalty.
    pub action_rate: f32,
    /// Feet air time reward.
    pub feet_air_time: f32,
    /// Penalty on a fall (not on a timeout), added after the clip at zero.
    pub termination: f32,
    /// Penalty per thigh or shank shape touching the terrain (legged_gym's `collision`, 1).
    #[serde(default = "one_f")]
    pub collision: f32,
    /// Penalty on joint positions outside the soft limits (legged_gym's `dof_pos_limits`,
    /// 0 for ANYmal).
    #[serde(default)]
    pub dof_pos_limits: f32,
    /// Penalty on base tilt, |g_xy|² (legged_gym's `orientation`: 0 in its rough-terrain
    /// configurations, 5 in the flat-ground ANYmal one).
    #[serde(default)]
    pub orientation: f32,
    /// Soft limits: this fraction of the URDF's range around its middle (legged_gym 1.0).
    #[serde(default = "one_f")]
    pub soft_dof_pos_limit: f32,
    /// Clip the per-step total at zero before the termination term (legged_gym: true).
    #[serde(default = "yes")]
    pub only_positive_rewards: bool,
}

fn one_f() -> f32 {
    1.0
}

/// One axis of a grid: `count` values evenly spaced from `min` to `max`.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct AxisSpec {
    /// First value.
    pub min: f64,
    /// Last value.
    pub max: f64,
    /// Number of values.
    pub count: usize,
}

impl AxisSpec {
    /// The values of the axis, evenly spaced, ends included.
    pub fn values(&self) -> Vec<f64> {
        match self.count {
            0 => vec![],
            1 => vec![self.min],
            n => (0..n)
                .map(|i| self.min + (self.max - self.min) * i as f64 / (n - 1) as f64)
                .collect(),
        }
    }
}

/// The paper's Table-1 grid of a robot.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct GridSpec {
    /// w1 (velocity tracking weight) axis.
    pub w1: AxisSpec,
    /// w2 (log10 of the torque penalty weight) axis.
    pub w2: AxisSpec,
    /// Agents (simulated robots) per cell.
    pub agents_per_cell: usize,
    /// PPO epochs per cell.
    pub epochs: u32,
}

/// PPO hyperparameters (rsl_rl's names).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PpoConfig {
    /// Actor MLP hidden sizes.
    pub actor_hidden: Vec<i64>,
    /// Critic MLP hidden sizes.
    pub critic_hidden: Vec<i64>,
    /// Initial action standard deviation.
    pub init_noise_std: f64,
    /// Surrogate clip.
    pub clip_param: f64,
    /// Discount.
    pub gamma: f64,
    /// GAE lambda.
    pub lam: f64,
    /// Value loss coefficient.
    pub value_loss_coef: f64,
    /// Entropy bonus coefficient.
    pub entropy_coef: f64,
    /// Initial learning rate.
    pub learning_rate: f64,
    /// Target KL of the adaptive learning-rate schedule.
    pub desired_kl: f64,
    /// Adapt the learning rate from the KL divergence.
    pub adaptive_lr: bool,
    /// Gradient norm clip.
    pub max_grad_norm: f64,
    /// Passes over each rollout.
    pub num_learning_epochs: usize,
    /// Mini-batches per pass.
    pub num_mini_batches: usize,
    /// Policy steps per environment per epoch.
    pub steps_per_env: usize,
    /// Clip the value loss like the surrogate.
    pub clip_value_loss: bool,
}

impl Default for PpoConfig {
    /// legged_gym's (rsl_rl's) defaults for ANYmal.
    fn default() -> Self {
        PpoConfig {
            actor_hidden: vec![512, 256, 128],
            critic_hidden: vec![512, 256, 128],
            init_noise_std: 1.0,
            clip_param: 0.2,
            gamma: 0.99,
            lam: 0.95,
            value_loss_coef: 1.0,
            entropy_coef: 0.01,
            learning_rate: 1e-3,
            desired_kl: 0.01,
            adaptive_lr: true,
            max_grad_norm: 1.0,
            num_learning_epochs: 5,
            num_mini_batches: 4,
            steps_per_env: 24,
            clip_value_loss: true,
        }
    }
}

impl PpoConfig {
    /// Overrides scalar hyperparameters by name (`clip_param = 0.1`, ...). Booleans take
    /// 0/1; integers must be whole. An unknown name is an error listing the known ones.
    pub fn apply_overrides(&mut self, overrides: &BTreeMap<String, f64>) -> Result<()> {
        for (key, &v) in overrides {
            let bad =
                |what: &str| Error::InvalidArgument(format!("ppo override {key} = {v}: {what}"));
            if !v.is_finite() {
                return Err(bad("value must be finite"));
            }
            let whole = || -> Result<usize> {
                if v >= 1.0 && v.fract() == 0.0 {
                    Ok(v as usize)
                } else {
                    Err(bad("expected a positive whole number"))
                }
            };
            match key.as_str() {
                "init_noise_std" => self.init_noise_std = v,
                "clip_param" => self.clip_param = v,
                "gamma" => self.gamma = v,
                "lam" => self.lam = v,
                "value_loss_coef" => self.value_loss_coef = v,
                "entropy_coef" => self.entropy_coef = v,
                "learning_rate" => self.learning_rate = v,
                "desired_kl" => self.desired_kl = v,
                "adaptive_lr" => self.adaptive_lr = v != 0.0,
                "max_grad_norm" => self.max_grad_norm = v,
                "num_learning_epochs" => self.num_learning_epochs = whole()?,
                "num_mini_batches" => self.num_mini_batches = whole()?,
                "steps_per_env" => self.steps_per_env = whole()?,
                "clip_value_loss" => self.clip_value_loss = v != 0.0,
                _ => {
                    return Err(bad(
                        "unknown hyperparameter; known: init_noise_std, clip_param, gamma, lam, \
                         value_loss_coef, entropy_coef, learning_rate, desired_kl, adaptive_lr, \
                         max_grad_norm, num_learning_epochs, num_mini_batches, steps_per_env, \
                         clip_value_loss",
                    ))
                }
            }
        }
        Ok(())
    }
}

/// The preset file as written.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct PresetFile {
    name: String,
    urdf: String,
    base_link: String,
    joints: Vec<String>,
    feet: Vec<String>,
    default_pose: Vec<f32>,
    nominal_base_height: f32,
    spawn_height: f32,
    control: ControlConfig,
    observation: ObservationConfig,
    commands: CommandConfig,
    reward: RewardConfig,
    grid: GridSpec,
    ppo: PpoConfig,
}

/// A robot preset: its URDF, control, observation, reward and grid settings.
#[derive(Debug, Clone)]
pub struct Preset {
    /// Robot name (`anymal`, `heavy`, ...).
    pub name: String,
    /// The preset's directory.
    pub dir: PathBuf,
    /// The URDF file.
    pub urdf_path: PathBuf,
    /// Name of the floating base link.
    pub base_link: String,
    /// Actuated joints in action order.
    pub joints: Vec<String>,
    /// Foot links.
    pub feet: Vec<String>,
    /// Default joint pose (rad), in `joints` order.
    pub default_pose: Vec<f32>,
    /// Standing base height (m).
    pub nominal_base_height: f32,
    /// Base height at spawn (m above the terrain).
    pub spawn_height: f32,
    /// PD control and physics.
    pub control: ControlConfig,
    /// Observation layout.
    pub observation: ObservationConfig,
    /// Command ranges.
    pub commands: CommandConfig,
    /// Fixed reward weights.
    pub reward: RewardConfig,
    /// Table-1 grid.
    pub grid: GridSpec,
    /// PPO hyperparameters.
    pub ppo: PpoConfig,
    /// sha256 of the preset file and the URDF: checkpoints record it.
    pub digest: String,
}

impl Preset {
    /// Loads the preset of a robot by name from [`robots_dir`], or from a preset directory
    /// when `robot` is a path (contains `/`), e.g. a robot kept outside this repository.
    pub fn load(robot: &str) -> Result<Preset> {
        let dir = if robot.contains('/') {
            PathBuf::from(robot)
        } else {
            robots_dir().join(robot)
        };
        if !dir.join("preset.toml").is_file() {
            let known = Self::available().join(", ");
            return Err(Error::Preset {
                path: dir.join("preset.toml"),
                message: format!("no preset for robot {robot:?}; known robots: {known}"),
            });
        }
        Self::load_from_dir(&dir)
    }

    /// The names of the robots in [`robots_dir`].
    pub fn available() -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(robots_dir())
            .into_iter()
            .flatten()
            .flatten()
            .filter(|e| e.path().join("preset.toml").is_file())
            .filter_map(|e| e.file_name().into_string().ok())
            .collect();
        names.sort();
        names
    }

    /// Loads `dir/preset.toml` and checks it against the URDF it names.
    ///
    /// A preset may start with `base = "DIR"` (relative to its own directory): it is then
    /// the preset of `DIR` with this file's values laid over it, table by table, so that a
    /// variant (e.g. a narrower command range) states only what it changes.
    pub fn load_from_dir(dir: &Path) -> Result<Preset> {
        let path = dir.join("preset.toml");
        let err = |message: String| Error::Preset {
            path: path.clone(),
            message,
        };
        let mut texts = Vec::new();
        let merged = Self::read_layers(dir, &mut texts, 0)?;
        let file: PresetFile = merged
            .try_into()
            .map_err(|e| err(format!("invalid preset: {e}")))?;
        // read_layers made it relative to the file that names it.
        let urdf_path = PathBuf::from(&file.urdf);
        let urdf_bytes = std::fs::read(&urdf_path)
            .map_err(|e| err(format!("cannot read urdf {}: {e}", urdf_path.display())))?;
        let mut problems = Vec::new();
        if file.joints.len() != 12 {
            problems.push(format!(
                "joints: expected 12 actuated joints, found {}",
                file.joints.len()
            ));
        }
        if file.default_pose.len() != file.joints.len() {
            problems.push(format!(
                "default_pose: expected {} values (one per joint), found {}",
                file.joints.len(),
                file.default_pose.len()
            ));
        }
        if file.feet.len() != 4 {
            problems.push(format!(
                "feet: expected 4 foot links, found {}",
                file.feet.len()
            ));
        }
        let c = &file.control;
        if !(c.sim_dt > 0.0 && c.sim_dt <= 0.02) {
            problems.push(format!(
                "control.sim_dt: expected (0, 0.02] s, found {}",
                c.sim_dt
            ));
        }
        if c.decimation == 0 || c.solver_iterations == 0 {
            problems.push("control.decimation and control.solver_iterations must be >= 1".into());
        }
        if c.torque_limit <= 0.0 || c.stiffness <= 0.0 {
            problems.push("control.torque_limit and control.stiffness must be > 0".into());
        }
        if file.observation.scan_x.is_empty() != file.observation.scan_y.is_empty() {
            problems
                .push("observation.scan_x and scan_y must both be empty or both non-empty".into());
        }
        if !problems.is_empty() {
            return Err(err(problems.join("; ")));
        }
        let mut h = Sha256::new();
        for t in &texts {
            h.update(t.as_bytes());
        }
        let digest = hex::encode(h.chain_update(&urdf_bytes).finalize());
        Ok(Preset {
            name: file.name,
            dir: dir.to_path_buf(),
            urdf_path,
            base_link: file.base_link,
            joints: file.joints,
            feet: file.feet,
            default_pose: file.default_pose,
            nominal_base_height: file.nominal_base_height,
            spawn_height: file.spawn_height,
            control: file.control,
            observation: file.observation,
            commands: file.commands,
            reward: file.reward,
            grid: file.grid,
            ppo: file.ppo,
            digest,
        })
    }

    /// `dir/preset.toml` as a TOML table with its `base` chain laid under it; the `urdf`
    /// of each layer is made absolute so that it stays relative to the file naming it.
    fn read_layers(dir: &Path, texts: &mut Vec<String>, depth: usize) -> Result<toml::Table> {
        let path = dir.join("preset.toml");
        let err = |message: String| Error::Preset {
            path: path.clone(),
            message,
        };
        if depth > 4 {
            return Err(err("base presets nest more than 4 deep (a cycle?)".into()));
        }
        let text = std::fs::read_to_string(&path).map_err(|e| err(format!("cannot read: {e}")))?;
        let mut table: toml::Table =
            toml::from_str(&text).map_err(|e| err(format!("invalid toml: {e}")))?;
        if let Some(toml::Value::String(u)) = table.get("urdf") {
            let abs = dir.join(u).to_string_lossy().into_owned();
            table.insert("urdf".into(), toml::Value::String(abs));
        }
        let base = match table.remove("base") {
            None => None,
            Some(toml::Value::String(b)) => Some(dir.join(b)),
            Some(other) => {
                return Err(err(format!(
                    "base must be a preset directory (a string), found {other}"
                )))
            }
        };
        let mut merged = match base {
            Some(b) => {
                if !b.join("preset.toml").is_file() {
                    return Err(err(format!(
                        "base preset {} has no preset.toml",
                        b.display()
                    )));
                }
                Self::read_layers(&b, texts, depth + 1)?
            }
            None => toml::Table::new(),
        };
        texts.push(text);
        merge(&mut merged, table);
        Ok(merged)
    }

    /// Policy time step (s): `sim_dt * decimation`.
    pub fn policy_dt(&self) -> f32 {
        self.control.sim_dt * self.control.decimation as f32
    }

    /// Number of height-scan points.
    pub fn scan_len(&self) -> usize {
        self.observation.scan_x.len() * self.observation.scan_y.len()
    }

    /// Observation size: 48 proprioceptive values plus the height scan.
    pub fn obs_dim(&self) -> usize {
        48 + self.scan_len()
    }

    /// Whether robots on `terrain` observe the height scan. Not on flat ground, as in
    /// legged_gym's flat configurations (`measure_heights = False`): there every point
    /// repeats the base height, and 187 copies of one input multiply Adam's effective
    /// learning rate along it (each weight moves by ~lr).
    pub fn scans_heights(terrain: crate::terrain::TerrainKind) -> bool {
        terrain != crate::terrain::TerrainKind::Flat
    }

    /// This preset as robots on `terrain` use it: without the height scan on flat ground.
    pub fn for_terrain(&self, terrain: crate::terrain::TerrainKind) -> Preset {
        let mut p = self.clone();
        if !Self::scans_heights(terrain) {
            p.observation.scan_x.clear();
            p.observation.scan_y.clear();
        }
        p
    }

    /// Observation size on `terrain`.
    pub fn obs_dim_on(&self, terrain: crate::terrain::TerrainKind) -> usize {
        self.obs_dim()
            - if Self::scans_heights(terrain) {
                0
            } else {
                self.scan_len()
            }
    }
}

/// Lays `top` over `base`: tables merge key by key, anything else is replaced.
fn merge(base: &mut toml::Table, top: toml::Table) {
    for (k, v) in top {
        match (base.get_mut(&k), v) {
            (Some(toml::Value::Table(b)), toml::Value::Table(t)) => merge(b, t),
            (_, v) => {
                base.insert(k, v);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_presets_load_with_table_one_grids() {
        let a = Preset::load("anymal").unwrap();
        assert_eq!(
            (a.grid.w1.count, a.grid.w2.count, a.grid.agents_per_cell),
            (4, 7, 146)
        );
        assert_eq!(a.obs_dim(), 48 + 17 * 11);
        assert_eq!(
            a.obs_dim_on(crate::terrain::TerrainKind::Rough),
            48 + 17 * 11
        );
        assert_eq!(a.obs_dim_on(crate::terrain::TerrainKind::Flat), 48);
        assert_eq!(
            a.for_terrain(crate::terrain::TerrainKind::Flat).obs_dim(),
            48
        );
        let h = Preset::load("heavy").unwrap();
        assert_eq!(
            (h.grid.w1.count, h.grid.w2.count, h.grid.agents_per_cell),
            (4, 4, 256)
        );
        let w1 = a.grid.w1.values();
        assert!((w1[1] - 5.3333).abs() < 1e-3 && w1[3] == 12.0);
    }

    #[test]
    fn a_preset_can_lay_its_changes_over_a_base() {
        let dir = tempfile::tempdir().unwrap();
        let base = robots_dir().join("anymal");
        std::fs::write(
            dir.path().join("preset.toml"),
            format!(
                "base = {:?}\nname = \"narrow\"\n[commands]\nforward_speed = [0.0, 1.0]\n",
                base.display().to_string()
            ),
        )
        .unwrap();
        let p = Preset::load_from_dir(dir.path()).unwrap();
        let a = Preset::load("anymal").unwrap();
        assert_eq!(p.name, "narrow");
        assert_eq!(p.commands.forward_speed, [0.0, 1.0]);
        assert_eq!(p.commands.heading, a.commands.heading);
        assert_eq!(p.control, a.control);
        assert_eq!(p.urdf_path, base.join("robot.urdf"));
        assert_ne!(p.digest, a.digest);
        let proof = Preset::load(
            robots_dir()
                .join("../bench/learning-proof")
                .to_str()
                .unwrap(),
        )
        .unwrap();
        assert_eq!(proof.commands.forward_speed, [0.0, 1.0]);
        assert_eq!(proof.reward, a.reward);
    }

    #[test]
    fn unknown_robot_names_the_known_ones() {
        let e = Preset::load("nope").unwrap_err().to_string();
        assert!(e.contains("anymal") && e.contains("heavy"), "{e}");
    }

    #[test]
    fn overrides_apply_and_reject_unknown_keys() {
        let mut p = Preset::load("anymal").unwrap().ppo;
        let mut o = BTreeMap::new();
        o.insert("clip_param".to_string(), 0.1);
        o.insert("num_mini_batches".to_string(), 2.0);
        p.apply_overrides(&o).unwrap();
        assert_eq!((p.clip_param, p.num_mini_batches), (0.1, 2));
        o.insert("bogus".to_string(), 1.0);
        assert!(p
            .apply_overrides(&o)
            .unwrap_err()
            .to_string()
            .contains("unknown hyperparameter"));
    }
}
