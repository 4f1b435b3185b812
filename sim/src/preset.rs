//! Robot presets: `robots/<name>/preset.toml` plus the URDF it names.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

use crate::error::{Error, Result};

use crate::terrain::TerrainKind;
pub use gaitsweep_model::preset::{
    available, preset_dir, robots_dir, AxisSpec, CommandConfig, ControlConfig, CurriculumConfig,
    DomainRandConfig, GridSpec, JointBackend, ObservationConfig, PpoConfig, PresetFile,
    ResetConfig, RewardConfig, TerrainOverrides, TerrainSettings,
};

/// A robot preset: its URDF, control, observation, reward and grid settings.
#[derive(Debug, Clone)]
pub struct Preset {
    /// Robot name (`anymal`, `heavy`, ...).
    pub name: String,
    /// The preset's directory.
    pub dir: PathBuf,
    /// The URDF file.
    pub urdf_path: PathBuf,
    /// The URDF file's text, read with the preset: every environment built from this preset
    /// parses this text, so a cell simulates the robot its preset digest names, also if the
    /// file changes or goes away while the cell trains.
    pub urdf_text: std::sync::Arc<str>,
    /// Name of the floating base link.
    pub base_link: String,
    /// Actuated joints in action order.
    pub joints: Vec<String>,
    /// Foot links.
    pub feet: Vec<String>,
    /// Default joint pose (rad), in `joints` order.
    pub default_pose: Vec<f32>,
    /// The left-right mirror of the joints as written (`[-]JOINT` per joint, see
    /// [`crate::mirror::joint_map`]); checked when the symmetry loss or the mirrored
    /// samples use it, so that a preset based on another robot's loads without restating
    /// it. Empty: none.
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
    /// PPO hyperparameters (before [`Preset::on_terrain`]).
    pub ppo: PpoConfig,
    /// Domain randomization and observation noise in training (before
    /// [`Preset::on_terrain`]).
    pub domain_rand: DomainRandConfig,
    /// Randomized episode starts.
    pub reset: ResetConfig,
    /// The terrain curriculum.
    pub curriculum: CurriculumConfig,
    /// What differs by terrain (`[terrain.<kind>.ppo]`, `[terrain.<kind>.domain_rand]`).
    pub terrain: BTreeMap<TerrainKind, TerrainOverrides>,
    /// sha256 of the preset file and the URDF: checkpoints record it.
    pub digest: String,
}

impl Preset {
    /// Loads the preset of a robot by name from [`robots_dir`], or from a preset directory
    /// when `robot` is a path (contains `/`), e.g. a robot kept outside this repository.
    pub fn load(robot: &str) -> Result<Preset> {
        Self::load_from_dir(&preset_dir(robot)?)
    }

    /// The names of the robots in [`robots_dir`].
    pub fn available() -> Vec<String> {
        available()
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
        let (file, texts) = PresetFile::read(dir)?;
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
        let d = &file.domain_rand;
        if !(d.friction_range[0] >= 0.0 && d.friction_range[0] <= d.friction_range[1]) {
            problems.push(format!(
                "domain_rand.friction_range: expected [lo, hi] with 0 <= lo <= hi, found {:?}",
                d.friction_range
            ));
        }
        if d.push_robots && !(d.push_interval_s > 0.0) {
            problems.push(format!(
                "domain_rand.push_interval_s: expected > 0 s, found {}",
                d.push_interval_s
            ));
        }
        let noise = [
            d.noise_level,
            d.noise_lin_vel,
            d.noise_ang_vel,
            d.noise_gravity,
            d.noise_dof_pos,
            d.noise_dof_vel,
            d.noise_height,
            d.max_push_vel_xy,
        ];
        if noise.iter().any(|v| !(*v >= 0.0 && v.is_finite())) {
            problems.push(
                "domain_rand: noise_level, the noise scales and max_push_vel_xy must be finite and >= 0"
                    .into(),
            );
        }
        let r = &file.reset;
        if !(r.dof_pos_scale[0] >= 0.0
            && r.dof_pos_scale[0] <= r.dof_pos_scale[1]
            && r.dof_pos_scale[1].is_finite())
        {
            problems.push(format!(
                "reset.dof_pos_scale: expected [lo, hi] with 0 <= lo <= hi, found {:?}",
                r.dof_pos_scale
            ));
        }
        if !(r.base_vel >= 0.0 && r.base_vel.is_finite()) {
            problems.push(format!(
                "reset.base_vel: expected a finite value >= 0 m/s, found {}",
                r.base_vel
            ));
        }
        if !problems.is_empty() {
            return Err(err(problems.join("; ")));
        }
        let mut h = Sha256::new();
        for t in &texts {
            h.update(t.as_bytes());
        }
        let digest = hex::encode(h.chain_update(&urdf_bytes).finalize());
        let urdf_text = String::from_utf8(urdf_bytes).map_err(|e| {
            err(format!(
                "urdf {} is not UTF-8 text ({e}): save it as UTF-8",
                urdf_path.display()
            ))
        })?;
        Ok(Preset {
            name: file.name,
            dir: dir.to_path_buf(),
            urdf_path,
            urdf_text: urdf_text.into(),
            base_link: file.base_link,
            joints: file.joints,
            feet: file.feet,
            default_pose: file.default_pose,
            mirror: file.mirror,
            nominal_base_height: file.nominal_base_height,
            spawn_height: file.spawn_height,
            control: file.control,
            observation: file.observation,
            commands: file.commands,
            reward: file.reward,
            grid: file.grid,
            ppo: file.ppo,
            domain_rand: file.domain_rand,
            reset: file.reset,
            curriculum: file.curriculum,
            terrain: file.terrain,
            digest,
        })
    }

    /// The parts of this preset that decide a cell's settings
    /// ([`gaitsweep_model::CellSettings::resolve`]).
    pub fn settings(&self) -> gaitsweep_model::cell_settings::PresetSettings<'_> {
        gaitsweep_model::cell_settings::PresetSettings {
            ppo: &self.ppo,
            domain_rand: &self.domain_rand,
            reward: &self.reward,
            by_terrain: &self.terrain,
        }
    }

    /// This preset as a cell on `terrain` with `budget` epochs trains with it: `ppo`,
    /// `domain_rand` and `reward` as [`gaitsweep_model::CellSettings::resolve`] decides them
    /// (terrain tables, then `overrides`, then the schedule in epochs of `budget`).
    pub fn for_cell(
        &self,
        terrain: TerrainKind,
        overrides: &std::collections::BTreeMap<String, f64>,
        budget: u32,
    ) -> Result<Preset> {
        let cell =
            gaitsweep_model::CellSettings::resolve(self.settings(), terrain, overrides, budget)?;
        Ok(Preset {
            ppo: cell.ppo,
            domain_rand: cell.domain_rand,
            reward: cell.reward,
            ..self.clone()
        })
    }

    /// This preset's `ppo`, `domain_rand` and `reward` with the terrain's
    /// `[terrain.<kind>.*]` tables laid over them (checked when it was loaded), before any
    /// override or schedule: what [`Preset::for_cell`] starts from.
    pub fn on_terrain(&self, terrain: TerrainKind) -> Result<Preset> {
        let TerrainSettings {
            ppo,
            domain_rand,
            reward,
        } = gaitsweep_model::preset::settings_on(
            &self.ppo,
            &self.domain_rand,
            &self.reward,
            &self.terrain,
            terrain,
        )?;
        Ok(Preset {
            ppo,
            domain_rand,
            reward,
            ..self.clone()
        })
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

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;

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
        // The demo's flat recipe: anymal's reward but for the heading weight.
        assert_eq!((proof.reward.w3_heading, a.reward.w3_heading), (0.5, 6.0));
        assert_eq!(
            RewardConfig {
                w3_heading: 0.5,
                ..a.reward.clone()
            },
            proof.reward
        );
        assert_eq!(
            (proof.ppo.init_noise_std, proof.ppo.mirror_loss_coef),
            (0.3, 0.0)
        );
    }

    /// Session 35: a cell's final evaluation failed because the robot's files were deleted
    /// while it trained. A loaded preset holds its URDF's text, and environments are built
    /// from it, not from the file.
    #[test]
    fn a_loaded_preset_needs_its_files_no_more() {
        let dir = tempfile::tempdir().unwrap();
        let copy = dir.path().join("anymal");
        std::fs::create_dir(&copy).unwrap();
        for f in ["preset.toml", "robot.urdf"] {
            std::fs::copy(robots_dir().join("anymal").join(f), copy.join(f)).unwrap();
        }
        let p = Preset::load_from_dir(&copy).unwrap();
        assert_eq!(p.digest, Preset::load("anymal").unwrap().digest);
        std::fs::remove_dir_all(&copy).unwrap();
        let model = crate::urdf::RobotModel::load(&p).unwrap();
        assert!(model.total_mass > 10.0, "{}", model.total_mass);
        let e = Preset::load_from_dir(&copy).unwrap_err().to_string();
        assert!(e.contains("preset.toml"), "{e}");
    }

    /// Issue 39: a sweep's grids on different terrains must differ only in the ground. Every
    /// shipped robot trains with the same PPO, reward and domain-randomisation settings on
    /// every terrain (the height scan, on off flat ground, is the only difference legged_gym
    /// makes), and its schedules scale with the cell's budget.
    #[test]
    fn a_cell_on_every_terrain_uses_the_same_recipe() {
        for robot in gaitsweep_model::preset::available() {
            let p = Preset::load(&robot).unwrap();
            assert!(
                p.terrain.is_empty(),
                "{robot} has terrain tables: {:?}",
                p.terrain.keys()
            );
            for t in TerrainKind::ALL {
                let on = p.on_terrain(t).unwrap();
                assert_eq!(on.reward, p.reward, "{robot} on {t}: reward weights differ");
                assert_eq!(on.ppo, p.ppo, "{robot} on {t}: ppo differs");
                assert_eq!(
                    on.domain_rand, p.domain_rand,
                    "{robot} on {t}: domain_rand differs"
                );
            }
            assert!(
                p.ppo.noise_decay_start == 0 && p.ppo.noise_decay_epochs == 0,
                "{robot}: the anneal must be given as fractions of the epoch budget"
            );
            let mut short = p.ppo.clone();
            let mut long = p.ppo.clone();
            short.resolve_schedule(600).unwrap();
            long.resolve_schedule(3000).unwrap();
            // The shipped recipes anneal: a preset without one would pass the scaling below
            // as 0 == 0 and say nothing about its schedule.
            assert!(
                short.noise_decay_start > 0 && short.noise_decay_epochs > 0,
                "{robot}: the shipped recipe anneals its action std ({short:?})"
            );
            assert_eq!(
                long.noise_decay_start,
                5 * short.noise_decay_start,
                "{robot}"
            );
            assert_eq!(
                long.noise_decay_epochs,
                5 * short.noise_decay_epochs,
                "{robot}: the anneal's end scales with the budget too"
            );
        }
    }

    #[test]
    fn small_forward_commands_are_zeroed_as_legged_gym_unless_a_preset_turns_it_off() {
        for robot in ["anymal", "heavy"] {
            let c = Preset::load(robot).unwrap().commands;
            assert_eq!(c.zero_speed_below, 0.2, "{robot}: legged_gym's threshold");
            assert_eq!(c.forward_command(0.0), 0.0);
            assert_eq!(c.forward_command(0.19), 0.0);
            assert_eq!(c.forward_command(0.2), 0.2);
            assert_eq!(c.forward_command(1.7), 1.7);
        }
        let a = Preset::load("anymal").unwrap();
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join("preset.toml"),
            format!(
                "base = {:?}\n[commands]\nzero_speed_below = 0.0\n",
                robots_dir().join("anymal").display().to_string()
            ),
        )
        .unwrap();
        let c = Preset::load_from_dir(dir.path()).unwrap().commands;
        assert_eq!(c.forward_speed, a.commands.forward_speed);
        assert_eq!(c.forward_command(0.05), 0.05, "off when a preset sets 0");
        assert_eq!(c.forward_command(1.7), 1.7);
    }

    #[test]
    fn settings_can_differ_by_terrain_and_bad_ones_are_named() {
        let anymal = robots_dir().join("anymal").display().to_string();
        let dir = tempfile::tempdir().unwrap();
        let write = |extra: &str| {
            std::fs::write(
                dir.path().join("preset.toml"),
                format!("base = {anymal:?}\n{extra}\n"),
            )
            .unwrap()
        };
        write(
            "[terrain.stairs.ppo]\ninit_noise_std = 0.7\nnoise_decay_start = 40\n\
             [terrain.stairs.domain_rand]\nadd_noise = true\n\
             [terrain.stairs.reward]\nw3_heading = 4.0",
        );
        let p = Preset::load_from_dir(dir.path()).unwrap();
        let stairs = p.on_terrain(TerrainKind::Stairs).unwrap();
        assert_eq!(
            (stairs.ppo.init_noise_std, stairs.ppo.noise_decay_start),
            (0.7, 40)
        );
        assert!(stairs.domain_rand.add_noise && !p.domain_rand.add_noise);
        assert_eq!((stairs.reward.w3_heading, p.reward.w3_heading), (4.0, 6.0));
        assert_eq!(stairs.reward.lin_vel_z, p.reward.lin_vel_z);
        assert_eq!(stairs.ppo.num_learning_epochs, p.ppo.num_learning_epochs);
        assert_eq!(stairs.domain_rand.push_robots, p.domain_rand.push_robots);
        let flat = p.on_terrain(TerrainKind::Flat).unwrap();
        assert_eq!(
            (flat.ppo, flat.domain_rand, flat.reward),
            (p.ppo.clone(), p.domain_rand.clone(), p.reward.clone())
        );
        for (extra, names) in [
            (
                "[terrain.stairs.ppo]\nbogus = 1.0",
                ["terrain.stairs.ppo", "bogus"],
            ),
            (
                "[terrain.rough.domain_rand]\nadd_noise = 3",
                ["terrain.rough.domain_rand", "add_noise"],
            ),
            (
                "[terrain.rough.reward]\nw1 = 3",
                ["terrain.rough.reward", "w1"],
            ),
            ("[terrain.rough.gait]\nx = 3", ["terrain", "gait"]),
            ("[terrain.ice.ppo]\nentropy_coef = 0.0", ["ice", "rough"]),
        ] {
            write(extra);
            let e = Preset::load_from_dir(dir.path()).unwrap_err().to_string();
            assert!(names.iter().all(|n| e.contains(n)), "{extra}: {e}");
        }
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
