//! Legs that collide and joints that stop at their limits (real rapier worlds), staggered
//! episode starts in training and none in evaluation.

use std::sync::Arc;

use gaitsweep_sim::robot::RobotWorld;
use gaitsweep_sim::terrain::{generate, LevelParams, TerrainKind};
use gaitsweep_sim::urdf::RobotModel;
use gaitsweep_sim::{EnvConfig, EnvMode, Preset, VecEnv};

/// Kneeling pose: thighs straight down, shanks folded to the knee limit, so the knees
/// (thigh and shank ends) are the lowest points and the feet are up by the hips.
const KNEEL: [f32; 12] = [
    0.0, 0.0, -2.7, 0.0, 0.0, -2.7, 0.0, 0.0, -2.7, 0.0, 0.0, -2.7,
];

/// Knees are the shank bodies' origins: bodies 3, 6, 9, 12 (base first, then each joint's child).
const KNEES: [usize; 4] = [3, 6, 9, 12];

fn hold(world: &mut RobotWorld, targets: &[f32; 12], seconds: f32, dt: f32) -> [f32; 12] {
    let (mut q, mut qd, mut tau) = ([0.0; 12], [0.0; 12], [0.0; 12]);
    for _ in 0..(seconds / dt).round() as usize {
        world.step(targets, &mut q, &mut qd, &mut tau);
    }
    world.joint_state(&mut q, &mut qd);
    q
}

#[test]
fn a_kneeling_robot_dropped_on_a_stair_edge_stops_on_its_legs() {
    let p = Preset::load("anymal").unwrap();
    let model = RobotModel::load(&p).unwrap();
    let level = 9;
    let tile = Arc::new(generate(TerrainKind::Stairs, level, 0));
    let step = LevelParams::at(level);
    // Up-pyramid: the k-th step begins k * step_width in from the sub-tile edge at x = -4.
    // Put the front knees (0.35 m ahead of the base centre) 3 cm past the start of step 3.
    let edge_x = -4.0 + 3.0 * step.step_width;
    let x = edge_x + 0.03 - 0.35;
    let top = tile.height(edge_x + 0.1, 0.0);
    let below = tile.height(edge_x - 0.1, 0.0);
    assert!(
        top - below > 0.2,
        "no step at x = {edge_x}: {below} then {top}"
    );
    let mut w = RobotWorld::new(&p, &model, tile.clone());
    // Knees 5 cm above the step they fall on.
    w.reset(x, 0.0, top + 0.3 + 0.04 + 0.05, 0.0, &KNEEL);
    hold(&mut w, &KNEEL, 2.0, p.control.sim_dt);
    let bodies = w.body_positions();
    let mut legs_touch = false;
    for (leg, &k) in KNEES.iter().enumerate() {
        let knee = bodies[k];
        let ground = tile.height(knee.x, knee.y);
        eprintln!(
            "knee {leg}: ({:.3}, {:.3}, {:.3}), ground {ground:.3}",
            knee.x, knee.y, knee.z
        );
        // The knee is the thigh capsule's lowest point: resting, it lies on the ground.
        assert!(
            knee.z >= ground - 0.01,
            "knee {leg} at z {:.3} sank into the terrain at {ground:.3}",
            knee.z
        );
        legs_touch |= knee.z < ground + 0.06;
    }
    assert!(legs_touch, "no knee rests on the terrain");
    assert!(w.leg_contacts() >= 2, "{} leg contacts", w.leg_contacts());
    assert!(
        !w.base_contact(),
        "the base reached the ground: the legs did not hold it"
    );
    // Without leg shapes the knees would sink through the step to the base's height.
    let lowest = KNEES
        .iter()
        .map(|&k| bodies[k].z)
        .fold(f32::INFINITY, f32::min);
    assert!(
        lowest > -0.01,
        "a knee at {lowest:.3} passed through the stairs"
    );
}

#[test]
fn a_joint_driven_at_full_torque_stops_at_its_limit() {
    for robot in ["anymal", "heavy"] {
        let p = Preset::load(robot).unwrap();
        let model = RobotModel::load(&p).unwrap();
        let tile = Arc::new(generate(TerrainKind::Flat, 0, 0));
        for k in 0..12 {
            let [lo, hi] = model.joints[k].limits.unwrap();
            for (target, limit) in [(20.0f32, hi), (-20.0, lo)] {
                // The robot hangs in the air (no ground reaction to help or hinder); joint
                // k's PD target is far past the limit, so its motor saturates.
                let mut w = RobotWorld::new(&p, &model, tile.clone());
                w.reset(0.0, 0.0, 5.0, 0.0, &p.default_pose);
                let mut targets = [0.0f32; 12];
                targets.copy_from_slice(&p.default_pose);
                targets[k] = target;
                let (mut q, mut qd, mut tau) = ([0.0; 12], [0.0; 12], [0.0; 12]);
                let mut overshoot = 0.0f32;
                for _ in 0..(0.6 / p.control.sim_dt) as usize {
                    w.step(&targets, &mut q, &mut qd, &mut tau);
                    assert!(
                        tau[k].abs() >= p.control.torque_limit * 0.99,
                        "{robot} joint {k}: motor torque {} at q {} qd {}",
                        tau[k],
                        q[k],
                        qd[k]
                    );
                    overshoot = overshoot.max(q[k] - hi).max(lo - q[k]);
                }
                w.joint_state(&mut q, &mut qd);
                eprintln!(
                    "{robot} joint {k} limit {limit}: rest {:+.4} overshoot {overshoot:.4}",
                    q[k] - limit
                );
                assert!(
                    (q[k] - limit).abs() < 0.06,
                    "{robot} joint {k} ({}) rests at {:.3}, limit {limit}",
                    model.joints[k].name,
                    q[k]
                );
                assert!(
                    overshoot < 0.1,
                    "{robot} joint {k} ({}) overshot its limit by {overshoot:.3} rad",
                    model.joints[k].name
                );
            }
        }
    }
}

#[test]
fn the_urdf_limits_are_read_and_the_default_pose_must_lie_inside() {
    let p = Preset::load("anymal").unwrap();
    let model = RobotModel::load(&p).unwrap();
    assert_eq!(model.joints[0].limits, Some([-0.72, 0.72]));
    assert_eq!(model.joints[2].limits, Some([-2.7, -0.35]));
    let text = std::fs::read_to_string(&p.urdf_path).unwrap().replacen(
        "lower=\"-2.7\" upper=\"-0.35\"",
        "lower=\"-1.0\" upper=\"-0.35\"",
        1,
    );
    let e = RobotModel::from_str(&p.urdf_path, &text, &p)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("LF_KFE") && e.contains("default pose -1.6") && e.contains("outside the limits"),
        "{e}"
    );
    let legs: usize = model.links[1..].iter().map(|l| l.shapes.len()).sum();
    assert_eq!(legs, 8, "one thigh and one shank shape per leg, feet apart");
}

fn env(mode: EnvMode, n: usize) -> VecEnv {
    let p = Preset::load("anymal").unwrap();
    VecEnv::new(
        &p,
        EnvConfig {
            mode,
            terrain: TerrainKind::Flat,
            num_envs: n,
            w1: 7.0,
            w2: -6.0,
            seed: 5,
            difficulty: Some(0),
            episode_seconds: 2.0,
        },
    )
    .unwrap()
}

#[test]
fn training_staggers_episode_starts_and_evaluation_does_not() {
    let mut train = env(EnvMode::Train, 32);
    let starts = train.episode_steps();
    let max_steps = (2.0 / train.policy_dt()).round() as u32;
    let distinct: std::collections::BTreeSet<_> = starts.iter().collect();
    assert!(distinct.len() > 16, "starts {starts:?}");
    assert!(starts.iter().all(|&s| s < max_steps));
    // Robots standing still time out one by one, not all at one step.
    let zeros = vec![0.0; 32 * 12];
    let mut steps_with_done = 0;
    for _ in 0..max_steps {
        let r = train.step(&zeros).unwrap();
        if r.dones.iter().any(|d| *d) {
            steps_with_done += 1;
            assert!(r.dones.iter().zip(r.timeouts).all(|(d, t)| !d || *t));
        }
    }
    assert!(steps_with_done > 10, "{steps_with_done} steps had a reset");
    let eval = env(EnvMode::Eval, 8);
    assert!(eval.episode_steps().iter().all(|&s| s == 0));
}

/// A quadruped with other link and joint names, limits and leg shapes (boxes and
/// capsules) loads with only a preset that names them, and walks in a VecEnv.
#[test]
fn a_quadruped_with_other_names_and_shapes_loads_with_only_a_preset() {
    let dir = tempfile::tempdir().unwrap();
    let inertial = |m: f32| {
        format!(
            r#"<inertial><origin xyz="0 0 -0.1" rpy="0 0 0"/><mass value="{m}"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.005"/></inertial>"#
        )
    };
    let mut urdf = String::from(
        r#"<?xml version="1.0"?><robot name="other"><link name="trunk"><inertial><origin xyz="0 0 0" rpy="0 0 0"/><mass value="8"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.3" iyz="0" izz="0.3"/></inertial><collision><geometry><box size="0.6 0.3 0.15"/></geometry></collision></link>"#,
    );
    let mut joints = Vec::new();
    let mut feet = Vec::new();
    for (leg, x, y) in [
        ("FL", 0.25, 0.12),
        ("FR", 0.25, -0.12),
        ("RL", -0.25, 0.12),
        ("RR", -0.25, -0.12),
    ] {
        for (j, parent, child, origin, axis, lim, shape) in [
            ("hip", "trunk".to_string(), format!("{leg}_hip"), format!("{x} {y} 0"), "1 0 0", "-0.8 0.8", String::new()),
            ("thigh", format!("{leg}_hip"), format!("{leg}_thigh"), "0 0 0".into(), "0 1 0", "-1.5 3.0",
             r#"<collision><origin xyz="0 0 -0.1" rpy="0 0 0"/><geometry><box size="0.04 0.03 0.16"/></geometry></collision>"#.into()),
            ("calf", format!("{leg}_thigh"), format!("{leg}_calf"), "0 0 -0.2".into(), "0 1 0", "-2.7 -0.6",
             r#"<collision><origin xyz="0 0 -0.08" rpy="0 0 0"/><geometry><capsule radius="0.015" length="0.1"/></geometry></collision>"#.into()),
        ] {
            urdf += &format!("<link name=\"{child}\">{}{shape}</link>", inertial(0.6));
            urdf += &format!(
                r#"<joint name="{leg}_{j}_joint" type="revolute"><parent link="{parent}"/><child link="{child}"/><origin xyz="{origin}" rpy="0 0 0"/><axis xyz="{axis}"/><limit effort="30" velocity="20" lower="{}" upper="{}"/></joint>"#,
                lim.split(' ').next().unwrap(),
                lim.split(' ').nth(1).unwrap()
            );
            joints.push(format!("\"{leg}_{j}_joint\""));
        }
        urdf += &format!(
            r#"<link name="{leg}_foot"><collision><geometry><sphere radius="0.02"/></geometry></collision></link><joint name="{leg}_foot_fixed" type="fixed"><parent link="{leg}_calf"/><child link="{leg}_foot"/><origin xyz="0 0 -0.2" rpy="0 0 0"/></joint>"#
        );
        feet.push(format!("\"{leg}_foot\""));
    }
    urdf += "</robot>";
    std::fs::write(dir.path().join("other.urdf"), urdf).unwrap();
    let base = gaitsweep_sim::preset::robots_dir().join("anymal");
    std::fs::write(
        dir.path().join("preset.toml"),
        format!(
            "base = {:?}\nname = \"other\"\nurdf = \"other.urdf\"\nbase_link = \"trunk\"\njoints = [{}]\nfeet = [{}]\n\
             default_pose = [0.0, 0.8, -1.5, 0.0, 0.8, -1.5, 0.0, 0.8, -1.5, 0.0, 0.8, -1.5]\n\
             nominal_base_height = 0.3\nspawn_height = 0.36\n[control]\nstiffness = 40.0\ndamping = 1.0\ntorque_limit = 30.0\n",
            base.display().to_string(),
            joints.join(", "),
            feet.join(", ")
        ),
    )
    .unwrap();
    let p = Preset::load_from_dir(dir.path()).unwrap();
    let model = RobotModel::load(&p).unwrap();
    assert_eq!(model.joints[2].limits, Some([-2.7, -0.6]));
    let legs: usize = model.links[1..].iter().map(|l| l.shapes.len()).sum();
    assert_eq!(legs, 8, "a box thigh and a capsule calf per leg");
    let mut e = VecEnv::new(
        &p,
        EnvConfig {
            mode: EnvMode::Train,
            terrain: TerrainKind::Rough,
            num_envs: 4,
            w1: 7.0,
            w2: -6.0,
            seed: 1,
            difficulty: Some(2),
            episode_seconds: 20.0,
        },
    )
    .unwrap();
    let zeros = vec![0.0; 4 * 12];
    for _ in 0..50 {
        let r = e.step(&zeros).unwrap();
        assert!(r.obs.iter().all(|v| v.is_finite()));
    }
}
