//! Robot preset files: `robots/<name>/preset.toml` (control, observation, commands,
//! reward, Table-1 grid, PPO), read with their `base` chain. The simulator checks a preset
//! against its URDF and builds robots from it (`gaitsweep_sim::Preset`).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::terrain::TerrainKind;

pub use crate::ppo_config::PpoConfig;

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
    pub joints: JointBackend,
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
    /// How capsules (legs, and a capsule base) touch a heightfield terrain:
    /// `closed_form` (default: at most three contacts per capsule, `gaitsweep_sim::contact`)
    /// or `parry` (parry's one manifold per triangle, the rule before 2026-12-02).
    #[serde(default)]
    pub capsule_contacts: CapsuleContacts,
    /// Episode length (s) during training.
    pub episode_seconds: f32,
}

fn default_backend() -> JointBackend {
    JointBackend::Multibody
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
    /// A drawn forward speed below this (m/s) is commanded as 0: the robot stands and turns
    /// to its heading (legged_gym's `_resample_commands` zeroes commands under 0.2 m/s).
    /// Default 0: every drawn speed is commanded.
    #[serde(default)]
    pub zero_speed_below: f32,
}

impl CommandConfig {
    /// The forward speed commanded for a speed drawn from `forward_speed`.
    pub fn forward_command(&self, drawn: f32) -> f32 {
        if drawn.abs() < self.zero_speed_below {
            0.0
        } else {
            drawn
        }
    }
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

/// legged_gym's domain randomization and observation noise, applied in training only (its
/// `play.py` turns all of them off, and so does the evaluation). Defaults are legged_gym's
/// `LeggedRobotCfg` (`noise`, `domain_rand`), so a preset without this table gets them.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct DomainRandConfig {
    /// Uniform noise on the observations (`noise.add_noise`).
    pub add_noise: bool,
    /// Multiplies every noise scale (`noise.noise_level`).
    pub noise_level: f32,
    /// Noise half-widths in physical units, before the observation scales
    /// (`noise.noise_scales`): base linear velocity (m/s).
    pub noise_lin_vel: f32,
    /// Base angular velocity (rad/s).
    pub noise_ang_vel: f32,
    /// Projected gravity (unit vector components).
    pub noise_gravity: f32,
    /// Joint positions (rad).
    pub noise_dof_pos: f32,
    /// Joint velocities (rad/s).
    pub noise_dof_vel: f32,
    /// Height scan (m).
    pub noise_height: f32,
    /// Robot shapes get a friction drawn per robot from `friction_range`
    /// (`domain_rand.randomize_friction`); the terrain keeps `control.friction`.
    pub randomize_friction: bool,
    /// Friction range of the robot's shapes.
    pub friction_range: [f32; 2],
    /// Every `push_interval_s` the base's horizontal velocity is set to a random one of up
    /// to `max_push_vel_xy` per axis (`domain_rand.push_robots`).
    pub push_robots: bool,
    /// Seconds between pushes.
    pub push_interval_s: f32,
    /// Largest pushed velocity per horizontal axis (m/s).
    pub max_push_vel_xy: f32,
}

impl Default for DomainRandConfig {
    fn default() -> Self {
        DomainRandConfig {
            add_noise: true,
            noise_level: 1.0,
            noise_lin_vel: 0.1,
            noise_ang_vel: 0.2,
            noise_gravity: 0.05,
            noise_dof_pos: 0.01,
            noise_dof_vel: 1.5,
            noise_height: 0.1,
            randomize_friction: true,
            friction_range: [0.5, 1.25],
            push_robots: true,
            push_interval_s: 15.0,
            max_push_vel_xy: 1.0,
        }
    }
}

impl DomainRandConfig {
    /// Everything off (evaluation, and presets that opt out).
    pub fn off() -> Self {
        DomainRandConfig {
            add_noise: false,
            randomize_friction: false,
            push_robots: false,
            ..Self::default()
        }
    }
}

/// How an episode starts. legged_gym's `_reset_dofs` and `_reset_root_states` start every
/// joint at its default angle times a factor drawn from `dof_pos_scale` (here clamped to
/// the joint's limits) and give the base a linear and angular velocity drawn per axis from
/// `[-base_vel, base_vel]`, in training and in `play.py` alike; [`ResetConfig::legged_gym`]
/// is that setting. The default starts at the default pose, at rest: with legged_gym's
/// setting the flat learning-proof cell (low-noise PPO, seed 1) fell in 90.6% of its
/// deterministic evaluation at epoch 400 against 20.3% without (BENCHMARKS.md, session 6).
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct ResetConfig {
    /// Range of the factor on each default joint angle.
    pub dof_pos_scale: [f32; 2],
    /// Largest base velocity per axis (m/s and rad/s).
    pub base_vel: f32,
}

impl Default for ResetConfig {
    fn default() -> Self {
        Self::at_rest()
    }
}

impl ResetConfig {
    /// Every episode starts at the default pose, at rest.
    pub fn at_rest() -> Self {
        ResetConfig {
            dof_pos_scale: [1.0, 1.0],
            base_vel: 0.0,
        }
    }

    /// legged_gym's randomized starts: joints at 0.5 to 1.5 times their default angle,
    /// base velocities up to 0.5 m/s and rad/s per axis.
    pub fn legged_gym() -> Self {
        ResetConfig {
            dof_pos_scale: [0.5, 1.5],
            base_vel: 0.5,
        }
    }
}

/// legged_gym's terrain curriculum (rough ground and stairs; the evaluation runs at a fixed
/// level and does not use it).
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct CurriculumConfig {
    /// A robot that walks out of the last level goes to a level drawn uniformly from all of
    /// them, as legged_gym's `_update_terrain_curriculum` sends "robots that solve the last
    /// level" to "a random one"; `false` keeps it on the last level, so that the robots pile
    /// up there (this project's rule up to session 21).
    pub random_after_last: bool,
}

impl Default for CurriculumConfig {
    fn default() -> Self {
        CurriculumConfig {
            random_after_last: true,
        }
    }
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

/// How capsule colliders touch a heightfield terrain (see `ControlConfig::capsule_contacts`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CapsuleContacts {
    /// The nearest surface point to each end cap and to the axis between them, in closed form.
    #[default]
    ClosedForm,
    /// parry's generic rule: one manifold (GJK and feature clipping) per triangle touched.
    Parry,
}

/// How the joints are simulated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum JointBackend {
    /// One reduced-coordinate multibody (exact joints, mass matrix rebuilt every substep).
    Multibody,
    /// Rigid bodies held together by impulse joint constraints.
    Impulse,
}

/// A preset file as written, with its `base` chain laid under it. The simulator checks it
/// against its URDF (`gaitsweep_sim::Preset`); the coordinator reads its grid and PPO
/// settings from it.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PresetFile {
    /// Robot name.
    pub name: String,
    /// The URDF path (absolute, or relative to the file that named it).
    pub urdf: String,
    /// Name of the floating base link.
    pub base_link: String,
    /// Actuated joints in action order.
    pub joints: Vec<String>,
    /// Foot links.
    pub feet: Vec<String>,
    /// Default joint pose (rad), in `joints` order.
    pub default_pose: Vec<f32>,
    /// The left-right mirror of the joints, in `joints` order: entry k names the joint whose
    /// value the mirrored robot's joint k takes, with a leading `-` where the sign flips
    /// (hip abduction). Empty: no mirror (the symmetry loss and the mirrored samples are then
    /// unavailable).
    #[serde(default)]
    pub mirror: Vec<String>,
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
    /// Domain randomization and observation noise in training (legged_gym's defaults).
    #[serde(default)]
    pub domain_rand: DomainRandConfig,
    /// How episodes start (default: at the default pose, at rest).
    #[serde(default)]
    pub reset: ResetConfig,
    /// The terrain curriculum (default: legged_gym's).
    #[serde(default)]
    pub curriculum: CurriculumConfig,
    /// Settings that differ by terrain (`[terrain.rough.ppo]`, `[terrain.rough.domain_rand]`,
    /// `[terrain.stairs.reward]`): laid over `ppo`, `domain_rand` and `reward` for a cell on
    /// that terrain (a spec's own `ppo` overrides go over them).
    #[serde(default)]
    pub terrain: BTreeMap<TerrainKind, TerrainOverrides>,
}

/// What a preset sets differently on one terrain: partial `[ppo]`, `[domain_rand]` and
/// `[reward]` tables, key by key over the preset's own.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct TerrainOverrides {
    /// Keys of `[ppo]`.
    #[serde(default)]
    pub ppo: toml::Table,
    /// Keys of `[domain_rand]`.
    #[serde(default)]
    pub domain_rand: toml::Table,
    /// Keys of `[reward]` (the fixed weights; w1 and w2 stay the grid's).
    #[serde(default)]
    pub reward: toml::Table,
}

/// The settings a cell on one terrain trains with.
#[derive(Debug, Clone, PartialEq)]
pub struct TerrainSettings {
    /// PPO hyperparameters.
    pub ppo: PpoConfig,
    /// Domain randomization and observation noise.
    pub domain_rand: DomainRandConfig,
    /// Fixed reward weights.
    pub reward: RewardConfig,
}

/// The `ppo`, `domain_rand` and `reward` of a cell on `terrain`: the preset's, with that
/// terrain's overrides from `by_terrain` laid over them.
pub fn settings_on(
    ppo: &PpoConfig,
    domain_rand: &DomainRandConfig,
    reward: &RewardConfig,
    by_terrain: &BTreeMap<TerrainKind, TerrainOverrides>,
    terrain: TerrainKind,
) -> Result<TerrainSettings> {
    let Some(o) = by_terrain.get(&terrain) else {
        return Ok(TerrainSettings {
            ppo: ppo.clone(),
            domain_rand: domain_rand.clone(),
            reward: reward.clone(),
        });
    };
    let bad =
        |table: &str, e: String| Error::InvalidArgument(format!("terrain.{terrain}.{table}: {e}"));
    Ok(TerrainSettings {
        ppo: lay_over(ppo, &o.ppo).map_err(|e| bad("ppo", e))?,
        domain_rand: lay_over(domain_rand, &o.domain_rand).map_err(|e| bad("domain_rand", e))?,
        reward: lay_over(reward, &o.reward).map_err(|e| bad("reward", e))?,
    })
}

fn lay_over<T: Serialize + DeserializeOwned>(
    value: &T,
    top: &toml::Table,
) -> std::result::Result<T, String> {
    let mut table = toml::Table::try_from(value).map_err(|e| e.to_string())?;
    merge(&mut table, top.clone());
    table
        .try_into()
        .map_err(|e: toml::de::Error| e.to_string().trim().to_owned())
}

/// The directory of a robot's preset: `robot` itself when it is a path (contains `/`),
/// else `robots_dir()/robot`; an unknown name is an error listing the known robots. A
/// relative path that does not exist from the current directory is taken from the directory
/// above `robots_dir()` (the source tree), so that a spec naming `bench/learning-proof`
/// resolves the same in the coordinator and in workers started from anywhere.
pub fn preset_dir(robot: &str) -> Result<PathBuf> {
    let dir = if robot.contains('/') {
        let path = PathBuf::from(robot);
        if path.is_relative() && !path.join("preset.toml").is_file() {
            robots_dir().join("..").join(path)
        } else {
            path
        }
    } else {
        robots_dir().join(robot)
    };
    if !dir.join("preset.toml").is_file() {
        let known = available().join(", ");
        return Err(Error::Preset {
            path: dir.join("preset.toml"),
            message: format!("no preset for robot {robot:?}; known robots: {known}"),
        });
    }
    Ok(dir)
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

impl PresetFile {
    /// Reads the preset of a robot by name or directory (see [`preset_dir`]).
    pub fn load(robot: &str) -> Result<PresetFile> {
        Ok(Self::read(&preset_dir(robot)?)?.0)
    }

    /// Reads `dir/preset.toml` with its `base` chain; also returns the text of every
    /// layer, base first (the simulator hashes them into the preset's digest).
    ///
    /// A preset may start with `base = "DIR"` (relative to its own directory): it is then
    /// the preset of `DIR` with this file's values laid over it, table by table, so that a
    /// variant (e.g. a narrower command range) states only what it changes.
    pub fn read(dir: &Path) -> Result<(PresetFile, Vec<String>)> {
        let mut texts = Vec::new();
        let merged = read_layers(dir, &mut texts, 0)?;
        let file: PresetFile = merged.try_into().map_err(|e| Error::Preset {
            path: dir.join("preset.toml"),
            message: format!("invalid preset: {e}"),
        })?;
        for &terrain in file.terrain.keys() {
            file.settings_on(terrain).map_err(|e| Error::Preset {
                path: dir.join("preset.toml"),
                message: e.to_string(),
            })?;
        }
        Ok((file, texts))
    }

    /// The parts of this preset that decide a cell's settings
    /// ([`crate::CellSettings::resolve`]).
    pub fn settings(&self) -> crate::cell_settings::PresetSettings<'_> {
        crate::cell_settings::PresetSettings {
            ppo: &self.ppo,
            domain_rand: &self.domain_rand,
            reward: &self.reward,
            by_terrain: &self.terrain,
        }
    }

    /// The `ppo`, `domain_rand` and `reward` of a cell on `terrain` (see [`settings_on`]).
    pub fn settings_on(&self, terrain: TerrainKind) -> Result<TerrainSettings> {
        settings_on(
            &self.ppo,
            &self.domain_rand,
            &self.reward,
            &self.terrain,
            terrain,
        )
    }
}

/// `dir/preset.toml` as a TOML table with its `base` chain laid under it; the `urdf` of
/// each layer is made absolute so that it stays relative to the file naming it.
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
            read_layers(&b, texts, depth + 1)?
        }
        None => toml::Table::new(),
    };
    texts.push(text);
    merge(&mut merged, table);
    Ok(merged)
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
