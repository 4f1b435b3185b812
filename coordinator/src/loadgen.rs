//! What the load bench (`loadbench`) sends: the metric set a real worker reports per
//! epoch, and the small measuring helpers it prints with. Kept in the library so that an
//! end-to-end test can check the list against what a real worker stores.

use std::collections::BTreeMap;
use std::path::Path;

/// Metric names the trainer reports after every epoch (anymal preset), as a real worker
/// stored them (`SELECT DISTINCT name FROM epoch_metrics`, eval/* aside).
pub const TRAINER_METRICS: &[&str] = &[
    "action_std",
    "curriculum/max_level",
    "curriculum/mean_level",
    "entropy",
    "grad_norm",
    "kl",
    "learning_rate",
    "loss/mirror",
    "loss/surrogate",
    "loss/value",
    "mean_episode_length",
    "mean_return",
    "mean_step_reward",
    "reward/action_rate",
    "reward/ang_vel_xy",
    "reward/collision",
    "reward/dof_acc",
    "reward/dof_pos_limits",
    "reward/feet_air_time",
    "reward/lin_vel_z",
    "reward/orientation",
    "reward/termination",
    "reward/torques",
    "reward/tracking_ang_vel",
    "reward/tracking_lin_vel",
    "samples_per_second",
    "time/inference",
    "time/sim",
    "time/update",
    "wall_seconds",
];

/// Metric names of an intermediate evaluation (every `eval.every` epochs) as a real worker
/// logs it off flat ground: every score component overall and at each default evaluation
/// level (`eval/level/<L>/...`), and the evaluation's wall time.
pub fn eval_metric_names() -> Vec<String> {
    use gaitsweep_model::{GaitScore, LevelScore};
    let levels = gaitsweep_core::defaults::EVAL_LEVELS
        .iter()
        .map(|&level| LevelScore {
            level,
            score: GaitScore::default(),
        })
        .collect();
    let mut names: Vec<String> = GaitScore::mean_of_levels(levels)
        .eval_metrics()
        .into_keys()
        .collect();
    names.push("eval/seconds".into());
    names.sort();
    names
}

/// One epoch's metrics as a simulated worker sends them: every trainer metric, plus the
/// evaluation's when `eval` is set. Values vary with the worker and epoch so that no two
/// rows are alike.
pub fn epoch_values(worker: usize, epoch: u32, eval: bool) -> BTreeMap<String, f64> {
    let base = worker as f64 * 1e-3 + epoch as f64 * 1e-2;
    let mut v: BTreeMap<String, f64> = TRAINER_METRICS
        .iter()
        .enumerate()
        .map(|(k, n)| (n.to_string(), base + k as f64))
        .collect();
    if eval {
        for n in eval_metric_names() {
            let x = match n.as_str() {
                "eval/score" => (worker % 97) as f64 / 97.0,
                "eval/robots" => 32.0,
                "eval/seconds" => 10.0,
                _ => 0.1,
            };
            v.insert(n, x);
        }
    }
    v
}

/// The value at quantile `q` (0..=1) of sorted samples, 0 when there are none.
pub fn quantile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let i = ((sorted.len() as f64 * q) as usize).min(sorted.len() - 1);
    sorted[i]
}

/// CPU seconds (user + system) and resident memory of a process, from `/proc`.
#[derive(Debug, Clone, Copy, Default)]
pub struct ProcUsage {
    /// User plus system CPU time, seconds.
    pub cpu_s: f64,
    /// Resident set now, MiB.
    pub rss_mib: f64,
    /// Peak resident set, MiB.
    pub peak_rss_mib: f64,
}

impl ProcUsage {
    /// Reads `/proc/<pid>/stat` and `/proc/<pid>/status` (Linux; zeros elsewhere).
    pub fn of(pid: u32) -> Self {
        let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).unwrap_or_default();
        // Fields after the command name, which is in parentheses and may hold spaces.
        let rest = stat.rsplit_once(')').map_or("", |(_, r)| r);
        let f: Vec<&str> = rest.split_whitespace().collect();
        // utime and stime are fields 14 and 15 of the line, in USER_HZ (100 on Linux).
        let ticks = |i: usize| f.get(i).and_then(|x| x.parse::<f64>().ok()).unwrap_or(0.0);
        let cpu_s = (ticks(11) + ticks(12)) / 100.0;
        let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap_or_default();
        let kib = |key: &str| {
            status
                .lines()
                .find_map(|l| l.strip_prefix(key))
                .and_then(|v| v.split_whitespace().next())
                .and_then(|v| v.parse::<f64>().ok())
                .unwrap_or(0.0)
        };
        ProcUsage {
            cpu_s,
            rss_mib: kib("VmRSS:") / 1024.0,
            peak_rss_mib: kib("VmHWM:") / 1024.0,
        }
    }
}

/// Bytes of a SQLite database with its write-ahead log.
pub fn database_bytes(db: &Path) -> u64 {
    let size = |p: &Path| std::fs::metadata(p).map_or(0, |m| m.len());
    let mut wal = db.as_os_str().to_owned();
    wal.push("-wal");
    size(db) + size(Path::new(&wal))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_epoch_carries_every_trainer_metric_and_evaluations_on_request() {
        let plain = epoch_values(3, 7, false);
        assert_eq!(plain.len(), TRAINER_METRICS.len());
        let eval = epoch_values(3, 7, true);
        assert_eq!(
            eval.len(),
            TRAINER_METRICS.len() + eval_metric_names().len()
        );
        assert!(eval.contains_key("eval/score"));
        assert!(eval.contains_key("eval/level/7/overspeed"));
        assert_ne!(epoch_values(3, 8, false), plain);
    }

    #[test]
    fn quantiles_of_sorted_samples() {
        let s: Vec<f64> = (1..=100).map(f64::from).collect();
        assert_eq!(quantile(&s, 0.5), 51.0);
        assert_eq!(quantile(&s, 0.99), 100.0);
        assert_eq!(quantile(&[], 0.5), 0.0);
    }

    #[test]
    fn this_process_uses_some_memory() {
        let u = ProcUsage::of(std::process::id());
        if cfg!(target_os = "linux") {
            assert!(u.rss_mib > 0.0 && u.peak_rss_mib >= u.rss_mib, "{u:?}");
        }
    }
}
