//! Every default a sweep or a local training run falls back to, decided here once. A
//! sweep's defaults are filled in when it is created (`gaitsweep_core::SweepSpec::resolve`),
//! so the stored spec and the tasks sent to workers carry concrete values; `worker train`,
//! `worker eval` and the trainer use the same constants (this module is re-exported as
//! `gaitsweep_core::defaults`).

use crate::TerrainKind;

/// Seed of every evaluation rollout: the same spawns and command schedule for every cell
/// and run, so that scores compare across the grid and a checkpoint always scores the same.
pub const EVAL_SEED: u64 = 0x5EED_E7A1;

/// Difficulty at which a curriculum-trained cell was evaluated before evaluations covered
/// several levels (the middle of 0..=9): the level of `worker eval` on a checkpoint when no
/// level is given, and of sweeps stored before per-level evaluation.
pub const CURRICULUM_EVAL_DIFFICULTY: u8 = 5;

/// Robots of the evaluation rollout that gives the gait score.
pub const EVAL_ROBOTS: usize = 64;

/// Length of the evaluation rollout in seconds (the paper's 20 s episodes).
pub const EVAL_SECONDS: f32 = 20.0;

/// Difficulty levels a cell trained with the curriculum (rough, stairs, slopes) is
/// evaluated at: its score is the mean over them, each level with `EVAL_ROBOTS` robots, so a
/// score covers the terrain from easy to hard rather than one level.
pub const EVAL_LEVELS: [u8; 4] = [0, 3, 5, 7];

/// The levels a cell on `terrain` is evaluated at: flat ground has no levels (0); a
/// terrain with a fixed training difficulty is evaluated at that difficulty; otherwise the
/// spec's `eval.levels`, or [`EVAL_LEVELS`].
pub fn eval_levels(terrain: TerrainKind, difficulty: Option<u8>, given: &[u8]) -> Vec<u8> {
    match (terrain, difficulty) {
        (TerrainKind::Flat, _) => vec![0],
        (_, Some(d)) if given.is_empty() => vec![d],
        _ if !given.is_empty() => given.to_vec(),
        _ => EVAL_LEVELS.to_vec(),
    }
}

/// Epochs between checkpoints when a spec does not say (resumption after a lost worker
/// starts from the last one).
pub const CHECKPOINT_EVERY: u32 = 100;

/// Checkpoint interval of a spec: unset takes [`CHECKPOINT_EVERY`], 0 means "only the
/// final checkpoint", which is an interval of the whole run.
pub fn checkpoint_every(given: Option<u32>, epochs: u32) -> u32 {
    match given {
        None => CHECKPOINT_EVERY,
        Some(0) => epochs.max(1),
        Some(n) => n,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn curriculum_terrains_are_scored_over_several_levels_and_flat_at_one() {
        assert_eq!(eval_levels(TerrainKind::Rough, None, &[]), EVAL_LEVELS);
        assert_eq!(eval_levels(TerrainKind::Stairs, None, &[2, 4]), [2, 4]);
        assert_eq!(eval_levels(TerrainKind::Stairs, Some(3), &[]), [3]);
        assert_eq!(eval_levels(TerrainKind::Flat, None, &[0, 3, 5, 7]), [0]);
    }

    #[test]
    fn checkpoint_interval_is_never_zero() {
        assert_eq!(checkpoint_every(None, 500), CHECKPOINT_EVERY);
        assert_eq!(checkpoint_every(Some(0), 500), 500);
        assert_eq!(checkpoint_every(Some(7), 500), 7);
        assert_eq!(checkpoint_every(Some(0), 0), 1);
    }
}
