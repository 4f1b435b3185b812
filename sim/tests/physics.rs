//! The simulation against the physical checks: standing, falling, determinism,
//! the height scan and URDF errors. Real rapier worlds, no mocks.

use gaitsweep_sim::{EnvConfig, Preset, TerrainKind, VecEnv};

fn env(robot: &str, terrain: TerrainKind, n: usize, seed: u64) -> VecEnv {
    let p = Preset::load(robot).unwrap();
    VecEnv::new(&p, EnvConfig { terrain, num_envs: n, w1: 7.0, w2: -6.0, seed, difficulty: Some(0), episode_seconds: 20.0 }).unwrap()
}

fn stands_still(robot: &str, terrain: TerrainKind) {
    let mut e = env(robot, terrain, 4, 1);
    let nominal = e.preset().nominal_base_height;
    let steps = (10.0 / e.policy_dt()).round() as usize;
    let zeros = vec![0.0; e.num_envs() * 12];
    for s in 0..steps {
        let r = e.step(&zeros).unwrap();
        assert!(!r.dones.iter().any(|d| *d), "{robot} on {terrain}: a robot fell or timed out at step {s} under zero action");
    }
    for (i, (h, tilt)) in e.base_heights_and_tilts().into_iter().enumerate() {
        eprintln!("{robot} {terrain} robot {i}: height {h:.4} (nominal {nominal}), tilt {tilt:.4}");
        assert!((h - nominal).abs() <= 0.05 * nominal, "{robot} on {terrain}: robot {i} base height {h} not within 5% of {nominal}");
        assert!(tilt < 0.1, "{robot} on {terrain}: robot {i} tilt {tilt}");
    }
}

#[test]
fn anymal_stands_on_flat() {
    stands_still("anymal", TerrainKind::Flat);
}

#[test]
fn anymal_stands_on_rough() {
    stands_still("anymal", TerrainKind::Rough);
}

#[test]
fn heavy_stands_on_flat() {
    stands_still("heavy", TerrainKind::Flat);
}

#[test]
fn heavy_stands_on_rough() {
    stands_still("heavy", TerrainKind::Rough);
}
