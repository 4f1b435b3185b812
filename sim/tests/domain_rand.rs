//! legged_gym's robustness settings: observation noise and pushes in training, none of
//! it in evaluation (real rapier worlds).

use std::sync::Arc;

use gaitsweep_sim::preset::{DomainRandConfig, JointBackend};
use gaitsweep_sim::robot::RobotWorld;
use gaitsweep_sim::terrain::{generate, TerrainKind};
use gaitsweep_sim::urdf::RobotModel;
use gaitsweep_sim::{EnvConfig, EnvMode, Preset, VecEnv};

fn env(p: &Preset, mode: EnvMode) -> VecEnv {
    VecEnv::new(
        p,
        EnvConfig {
            mode,
            terrain: TerrainKind::Flat,
            num_envs: 8,
            w1: 7.0,
            w2: -6.0,
            seed: 3,
            difficulty: Some(0),
            episode_seconds: 20.0,
        },
    )
    .unwrap()
}

/// Joint-position part of each robot's observation (after 3 + 3 + 3 + 3 values).
fn joint_obs(e: &VecEnv) -> Vec<f32> {
    let od = e.obs_dim();
    e.observations()
        .chunks(od)
        .flat_map(|o| o[12..24].to_vec())
        .collect()
}

#[test]
fn training_observations_are_noisy_and_evaluation_ones_are_not() {
    // robots/anymal trains without observation noise (its preset says why); legged_gym's
    // noise is the default of a preset that does not say.
    let mut noisy = Preset::load("anymal").unwrap();
    assert!(
        !noisy.domain_rand.add_noise,
        "the shipped anymal recipe has no observation noise"
    );
    noisy.domain_rand = DomainRandConfig::default();
    assert!(
        noisy.domain_rand.add_noise,
        "legged_gym's default adds noise"
    );
    let mut quiet = noisy.clone();
    quiet.domain_rand = DomainRandConfig::off();

    // Robots start at the default pose: without noise the joint observations are 0.
    let clean = joint_obs(&env(&quiet, EnvMode::Train));
    assert!(clean.iter().all(|v| v.abs() < 1e-3), "{clean:?}");
    let train = joint_obs(&env(&noisy, EnvMode::Train));
    let half = noisy.domain_rand.noise_dof_pos * noisy.observation.dof_pos_scale + 1e-3;
    assert!(
        train.iter().all(|v| v.abs() <= half),
        "noise beyond its scale: {train:?}"
    );
    let moved = train.iter().filter(|v| v.abs() > 1e-3).count();
    assert!(
        moved > train.len() / 2,
        "only {moved} of {} values noisy",
        train.len()
    );

    let a = env(&noisy, EnvMode::Eval);
    let b = env(&quiet, EnvMode::Eval);
    assert!(
        a.observations()
            .iter()
            .zip(b.observations())
            .all(|(x, y)| x.to_bits() == y.to_bits()),
        "evaluation observations depend on the noise settings"
    );
}

#[test]
fn a_push_sets_the_base_velocity_and_leaves_the_joints_alone() {
    for backend in [JointBackend::Impulse, JointBackend::Multibody] {
        let mut p = Preset::load("anymal").unwrap();
        p.control.joints = backend;
        pushed(&p);
    }
}

fn pushed(p: &Preset) {
    let model = RobotModel::load(p).unwrap();
    let mut w = RobotWorld::new(p, &model, Arc::new(generate(TerrainKind::Flat, 0, 0)));
    w.reset(0.0, 0.0, p.spawn_height, 0.0, &p.default_pose);
    let (mut q, mut qd, mut tau) = ([0.0; 12], [0.0; 12], [0.0; 12]);
    for _ in 0..200 {
        w.step(&p.default_pose, &mut q, &mut qd, &mut tau);
    }
    let (mut q0, mut qd0) = ([0.0; 12], [0.0; 12]);
    w.joint_state(&mut q0, &mut qd0);
    w.push_base(0.8, -0.6);
    let (mut q1, mut qd1) = ([0.0; 12], [0.0; 12]);
    w.joint_state(&mut q1, &mut qd1);
    for k in 0..12 {
        assert!(
            (qd1[k] - qd0[k]).abs() < 1e-4,
            "joint {k}: {} -> {}",
            qd0[k],
            qd1[k]
        );
    }
    // A multibody's bodies take their velocities from it during the step: read after one.
    w.step(&p.default_pose, &mut q, &mut qd, &mut tau);
    let v = w.base().linvel;
    let backend = &p.control.joints;
    assert!(
        (v.x - 0.8).abs() < 0.1 && (v.y + 0.6).abs() < 0.1,
        "{backend:?}: base velocity {v:?} after a push to (0.8, -0.6)"
    );
    // It moves off at that speed and keeps its feet.
    let x0 = w.base().pos.x;
    for _ in 0..20 {
        w.step(&p.default_pose, &mut q, &mut qd, &mut tau);
    }
    let dx = w.base().pos.x - x0;
    assert!(dx > 0.03, "pushed base moved {dx} m in 0.1 s");
    assert!(!w.base_contact());
}
