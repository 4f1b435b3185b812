//! How episodes start: at the default pose and at rest by default; with legged_gym's
//! randomized starts, joints scaled within their limits, feet never in the ground and
//! the base moving (real rapier worlds, both joint backends).

use gaitsweep_sim::preset::{JointBackend, ResetConfig};
use gaitsweep_sim::terrain::TerrainKind;
use gaitsweep_sim::{EnvConfig, EnvMode, Preset, VecEnv};

fn env(p: &Preset) -> VecEnv {
    VecEnv::new(
        p,
        EnvConfig {
            mode: EnvMode::Eval,
            terrain: TerrainKind::Flat,
            num_envs: 16,
            w1: 7.0,
            w2: -6.0,
            seed: 5,
            difficulty: Some(0),
            episode_seconds: 20.0,
        },
    )
    .unwrap()
}

#[test]
fn episodes_start_at_rest_by_default() {
    let p = Preset::load("anymal").unwrap();
    assert_eq!(p.reset, ResetConfig::at_rest());
    let e = env(&p);
    let od = e.obs_dim();
    for o in e.observations().chunks(od) {
        // Base velocities (0..6) and joint offsets from the default pose (12..24) are 0.
        assert!(o[0..6].iter().all(|v| v.abs() < 1e-4), "{:?}", &o[0..6]);
        assert!(o[12..24].iter().all(|v| v.abs() < 1e-4), "{:?}", &o[12..24]);
    }
}

#[test]
fn legged_gym_starts_scale_the_joints_within_limits_and_move_the_base() {
    for backend in [JointBackend::Impulse, JointBackend::Multibody] {
        let mut p = Preset::load("anymal").unwrap();
        p.control.joints = backend;
        p.reset = ResetConfig::legged_gym();
        let e = env(&p);
        let od = e.obs_dim();
        let scale = p.observation.dof_pos_scale;
        let mut moving = 0;
        for (i, o) in e.observations().chunks(od).enumerate() {
            for k in 0..12 {
                let q = p.default_pose[k] + o[12 + k] / scale;
                let d = p.default_pose[k];
                let (lo, hi) = if d >= 0.0 {
                    (0.5 * d, 1.5 * d)
                } else {
                    (1.5 * d, 0.5 * d)
                };
                assert!(
                    q >= lo - 1e-3 && q <= hi + 1e-3,
                    "{backend:?} robot {i} joint {k}: {q} outside [{lo}, {hi}]"
                );
            }
            if o[0..6].iter().any(|v| v.abs() > 1e-3) {
                moving += 1;
            }
            // No foot starts in the ground (foot spheres rest on z = radius at best).
            let (_, feet) = e.robot_geometry(i);
            let lowest = feet.iter().map(|f| f.z).fold(f32::INFINITY, f32::min);
            assert!(
                lowest > 0.0,
                "{backend:?} robot {i}: a foot starts at z {lowest}"
            );
        }
        assert_eq!(moving, 16, "{backend:?}: every base starts moving");
        // The joint scales differ between robots.
        let first: Vec<f32> = e.observations()[12..24].to_vec();
        let second: Vec<f32> = e.observations()[od + 12..od + 24].to_vec();
        assert_ne!(first, second);
    }
}
