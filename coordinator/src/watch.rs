//! `coordinator watch` on a terminal: one progress bar for the sweep (epochs of all cells,
//! epochs per second, ETA, cells done, best score) and one per running cell (epoch, mean
//! return). Not on a terminal, `watch` prints plain lines instead (cli.rs).

use gaitsweep_core::pb::{self, sweep_event::Kind};
use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::collections::BTreeMap;

/// The bars of one watched sweep.
pub struct WatchBars {
    multi: MultiProgress,
    sweep: ProgressBar,
    cells: BTreeMap<i64, ProgressBar>,
    /// Latest epoch of every cell (the sweep bar's position is their sum).
    epochs: BTreeMap<i64, u32>,
    epochs_per_cell: u32,
    cells_total: u32,
    cells_done: u32,
    best: Option<f64>,
}

fn cell_label(c: &pb::Cell) -> String {
    format!(
        "cell {:>4} {} w1 {:>6.3} w2 {:>7.3}{}",
        c.cell_id,
        c.terrain,
        c.w1,
        c.w2,
        if c.replicate > 0 {
            format!(" rep {}", c.replicate)
        } else {
            String::new()
        }
    )
}

/// `CELL_STATE_FAILED` -> `failed`.
fn name(wire: &str) -> String {
    wire.rsplit_once("_STATE_")
        .map_or(wire, |(_, n)| n)
        .to_lowercase()
}

impl WatchBars {
    /// Bars for `sweep` with its cells as they are now, drawn to stderr (`hidden` for tests).
    pub fn new(sweep: &pb::Sweep, cells: &[pb::Cell], hidden: bool) -> WatchBars {
        let target = if hidden {
            ProgressDrawTarget::hidden()
        } else {
            ProgressDrawTarget::stderr()
        };
        let multi = MultiProgress::with_draw_target(target);
        let epochs_per_cell = sweep.spec.as_ref().map_or(0, |s| s.epochs).max(1);
        let total = u64::from(epochs_per_cell) * u64::from(sweep.cells_total);
        let bar = multi.add(ProgressBar::new(total));
        bar.set_style(
            ProgressStyle::with_template(
                "sweep {prefix} [{bar:30}] {pos}/{len} epochs  {per_sec}  eta {eta}  {msg}",
            )
            .expect("valid template")
            .progress_chars("=> "),
        );
        bar.set_prefix(sweep.sweep_id.to_string());
        let mut w = WatchBars {
            multi,
            sweep: bar,
            cells: BTreeMap::new(),
            epochs: BTreeMap::new(),
            epochs_per_cell,
            cells_total: sweep.cells_total,
            cells_done: 0,
            best: None,
        };
        for c in cells {
            w.cell(c);
        }
        // Epochs trained before watching are not part of the rate.
        w.sweep.reset_elapsed();
        w.sweep.reset_eta();
        w
    }

    fn refresh(&mut self) {
        let pos: u64 = self.epochs.values().map(|e| u64::from(*e)).sum();
        self.sweep.set_position(pos);
        self.sweep.set_message(format!(
            "{}/{} cells done{}",
            self.cells_done,
            self.cells_total,
            self.best
                .map(|b| format!(", best score {b:.4}"))
                .unwrap_or_default()
        ));
    }

    fn cell_bar(&mut self, id: i64, label: impl FnOnce() -> String) -> &ProgressBar {
        let (multi, n) = (&self.multi, self.epochs_per_cell);
        self.cells.entry(id).or_insert_with(|| {
            let b = multi.add(ProgressBar::new(u64::from(n)));
            b.set_style(
                ProgressStyle::with_template("  {prefix} [{bar:20}] epoch {pos}/{len}  {msg}")
                    .expect("valid template")
                    .progress_chars("=> "),
            );
            b.set_prefix(label());
            b
        })
    }

    /// A cell changed state.
    pub fn cell(&mut self, c: &pb::Cell) {
        let state = pb::CellState::try_from(c.state).unwrap_or_default();
        let epochs = self.epochs.entry(c.cell_id).or_default();
        *epochs = (*epochs).max(c.epochs_done);
        match state {
            pb::CellState::Running => {
                let e = *epochs;
                self.cell_bar(c.cell_id, || cell_label(c))
                    .set_position(u64::from(e));
            }
            pb::CellState::Done
            | pb::CellState::Failed
            | pb::CellState::Cancelled
            | pb::CellState::Paused
            | pb::CellState::Stopped => {
                if state == pb::CellState::Done {
                    self.cells_done += 1;
                    // A done cell counts all its epochs.
                    self.epochs.insert(c.cell_id, self.epochs_per_cell);
                    if let Some(s) = c.score.as_ref().filter(|s| s.score.is_finite()) {
                        self.best = Some(self.best.map_or(s.score, |b| b.max(s.score)));
                    }
                }
                if let Some(b) = self.cells.remove(&c.cell_id) {
                    let end = match (state, c.score.as_ref()) {
                        (pb::CellState::Done, Some(s)) => format!(
                            "{}: score {:.4}, fall rate {:.0}%",
                            cell_label(c),
                            s.score,
                            100.0 * s.fall_rate
                        ),
                        (pb::CellState::Paused, _) => {
                            format!("{}: paused at epoch {}", cell_label(c), c.epochs_done)
                        }
                        _ => format!("{}: {}", cell_label(c), name(state.as_str_name())),
                    };
                    b.finish_and_clear();
                    self.multi.remove(&b);
                    let _ = self.multi.println(end);
                }
            }
            _ => {}
        }
        self.refresh();
    }

    /// A cell reported an epoch.
    pub fn progress(&mut self, p: &pb::CellProgress) {
        let e = self.epochs.entry(p.cell_id).or_default();
        *e = (*e).max(p.epoch);
        let id = p.cell_id;
        let bar = self.cell_bar(id, || format!("cell {id:>4}"));
        bar.set_position(u64::from(p.epoch));
        if let Some(r) = p.mean_return {
            bar.set_message(format!("mean return {r:.3}"));
        }
        self.refresh();
    }

    /// One event of the watch stream; true when the sweep has ended.
    pub fn event(&mut self, ev: &pb::SweepEvent) -> bool {
        match &ev.kind {
            Some(Kind::Cell(c)) => self.cell(c),
            Some(Kind::Progress(p)) => self.progress(p),
            Some(Kind::Promotion(p)) => {
                let cell = p.cell.clone().unwrap_or_default();
                let on = if p.terrain.is_empty() {
                    "overall".to_string()
                } else {
                    format!("on {}", p.terrain)
                };
                let _ = self.multi.println(format!(
                    "promoted {} {on} (score {:.4})",
                    cell_label(&cell),
                    cell.score.map_or(f64::NAN, |s| s.score)
                ));
            }
            Some(Kind::Decision(d)) => {
                let _ = self.multi.println(decision_line(d));
            }
            Some(Kind::Finished(s)) => {
                self.sweep.finish();
                let state = pb::SweepState::try_from(s.state).unwrap_or_default();
                let _ = self.multi.println(format!(
                    "sweep {} {}",
                    s.sweep_id,
                    name(state.as_str_name())
                ));
                return true;
            }
            None => {}
        }
        false
    }

    /// Epochs counted so far, of all.
    pub fn position(&self) -> (u64, u64) {
        (self.sweep.position(), self.sweep.length().unwrap_or(0))
    }

    /// Cells with a bar (running).
    pub fn running(&self) -> usize {
        self.cells.len()
    }
}

/// One line for a successive-halving decision (`watch` on a terminal and off it).
pub fn decision_line(d: &pb::RungDecision) -> String {
    format!(
        "cell {} {} at rung {} (epoch {}, score {:.4})",
        d.cell_id,
        if d.continued { "continues" } else { "stopped" },
        d.rung,
        d.epoch,
        d.score
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cell(id: i64, state: pb::CellState, epochs: u32, score: Option<f64>) -> pb::Cell {
        pb::Cell {
            cell_id: id,
            terrain: "flat".into(),
            state: state as i32,
            epochs_done: epochs,
            score: score.map(|s| pb::GaitScore {
                score: s,
                ..Default::default()
            }),
            ..Default::default()
        }
    }

    #[test]
    fn bars_follow_the_events() {
        let sweep = pb::Sweep {
            sweep_id: 1,
            cells_total: 2,
            spec: Some(pb::SweepSpec {
                epochs: 10,
                ..Default::default()
            }),
            ..Default::default()
        };
        let cells = [
            cell(1, pb::CellState::Running, 4, None),
            cell(2, pb::CellState::Queued, 0, None),
        ];
        let mut w = WatchBars::new(&sweep, &cells, true);
        assert_eq!((w.position(), w.running()), ((4, 20), 1));
        let progress = |id, epoch| pb::SweepEvent {
            kind: Some(Kind::Progress(pb::CellProgress {
                cell_id: id,
                epoch,
                mean_return: Some(1.0),
            })),
            ..Default::default()
        };
        assert!(!w.event(&progress(1, 6)));
        assert!(!w.event(&progress(2, 3)));
        assert_eq!((w.position(), w.running()), ((9, 20), 2));
        let done = pb::SweepEvent {
            kind: Some(Kind::Cell(cell(1, pb::CellState::Done, 10, Some(0.5)))),
            ..Default::default()
        };
        assert!(!w.event(&done));
        assert_eq!((w.position(), w.running()), ((13, 20), 1));
        assert_eq!(w.best, Some(0.5));
        let end = pb::SweepEvent {
            kind: Some(Kind::Finished(pb::Sweep::default())),
            ..Default::default()
        };
        assert!(w.event(&end));
    }
}
