//! Every default a sweep or a local training run falls back to, decided here once. A
//! sweep's defaults are filled in when it is created ([`crate::SweepSpec::resolve`]), so the
//! stored spec and the tasks sent to workers carry concrete values; `worker train` and
//! `worker eval` use the same constants for their flags.

/// Robots of the evaluation rollout that gives the gait score.
pub const EVAL_ROBOTS: usize = 64;

/// Length of the evaluation rollout in seconds (the paper's 20 s episodes).
pub const EVAL_SECONDS: f32 = 20.0;

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
    fn checkpoint_interval_is_never_zero() {
        assert_eq!(checkpoint_every(None, 500), CHECKPOINT_EVERY);
        assert_eq!(checkpoint_every(Some(0), 500), 500);
        assert_eq!(checkpoint_every(Some(7), 500), 7);
        assert_eq!(checkpoint_every(Some(0), 0), 1);
    }
}
