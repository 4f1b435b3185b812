//! A sweep's training speed for the live page's ETA, from its workers' recent attempts.

use crate::store::queries::AttemptSpan;

/// How far back an ended attempt still counts.
pub(super) const WINDOW_MS: i64 = 6 * 3_600_000;

/// Epochs a second the sweep trains now: one worker slot's speed (epochs over the wall time
/// of the attempts running now or ended in the last [`WINDOW_MS`], evaluations and uploads
/// included) times the attempts running. Only time a slot held one of the sweep's cells
/// counts, so a recording resumed after days away reads the speed it trains at, where its
/// epochs over its age would read it days slow. `None` while nothing runs or before the
/// first epoch.
pub(super) fn epochs_per_second(spans: &[AttemptSpan], now_ms: i64) -> Option<f64> {
    let running = spans.iter().filter(|s| s.ended_ms.is_none()).count();
    let (mut ms, mut epochs) = (0_i64, 0_i64);
    for s in spans {
        let end = s.ended_ms.unwrap_or(now_ms);
        if end < now_ms - WINDOW_MS {
            continue;
        }
        ms += (end - s.started_ms).max(0);
        epochs += s.epochs.max(0);
    }
    (running > 0 && epochs > 0 && ms > 0)
        .then(|| running as f64 * epochs as f64 * 1_000.0 / ms as f64)
}

#[cfg(test)]
mod tests {
    use super::{epochs_per_second, WINDOW_MS};
    use crate::store::queries::AttemptSpan;

    const HOUR: i64 = 3_600_000;

    fn span(started_h: f64, ended_h: Option<f64>, epochs: i64) -> AttemptSpan {
        AttemptSpan {
            started_ms: (started_h * HOUR as f64) as i64,
            ended_ms: ended_h.map(|h| (h * HOUR as f64) as i64),
            epochs,
        }
    }

    #[test]
    fn two_slots_at_three_seconds_an_epoch_train_two_thirds_of_an_epoch_a_second() {
        // Each slot: one cell ended (1,200 epochs in an hour) and one running (600 in half
        // an hour), so 3 s an epoch.
        let now = (100.0 * HOUR as f64) as i64;
        let spans = [
            span(98.5, Some(99.5), 1_200),
            span(99.5, None, 600),
            span(98.5, Some(99.5), 1_200),
            span(99.5, None, 600),
        ];
        let r = epochs_per_second(&spans, now).unwrap();
        assert!((r - 2.0 / 3.0).abs() < 1e-9, "{r}");
    }

    #[test]
    fn time_away_from_the_sweep_does_not_slow_it() {
        // A sitting stopped at hour 10 and resumed at hour 70: the last sitting's attempt
        // ended long ago and the one running now measures the speed alone.
        let now = 71 * HOUR;
        let spans = [span(9.0, Some(10.0), 1_200), span(70.0, None, 1_200)];
        let r = epochs_per_second(&spans, now).unwrap();
        assert!((r - 1_200.0 / 3_600.0).abs() < 1e-9, "{r}");
        // Within the window it counts: one slot, 2,400 epochs in 2 hours of leases.
        let spans = [span(69.0, Some(70.0), 1_200), span(70.0, None, 1_200)];
        let r = epochs_per_second(&spans, now).unwrap();
        assert!((r - 1_200.0 / 3_600.0).abs() < 1e-9, "{r}");
        const { assert!(WINDOW_MS < 60 * HOUR) };
    }

    #[test]
    fn nothing_running_or_nothing_trained_has_no_speed() {
        let now = 10 * HOUR;
        assert_eq!(epochs_per_second(&[], now), None);
        assert_eq!(
            epochs_per_second(&[span(8.0, Some(9.0), 1_200)], now),
            None,
            "no worker holds a cell"
        );
        assert_eq!(
            epochs_per_second(&[span(9.99, None, 0)], now),
            None,
            "before the first epoch"
        );
    }
}
