//! Which CPUs trained each cell. The same seed trains differently on two CPU models (their
//! math libraries take different code paths, BENCHMARKS session 35), and a recording spread
//! over several sittings may move between machines in the middle of a cell, so a result
//! names the CPUs it was trained on, with the epochs each one trained.

use super::ReportCell;
use crate::store::queries::AttemptCpu;
use std::collections::BTreeMap;

/// What a worker that did not report its CPU model (older workers) is shown as.
pub const UNRECORDED_CPU: &str = "CPU not recorded";

/// Epochs `from..to` of a cell, trained on one CPU model.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CpuSpan {
    /// CPU model ([`UNRECORDED_CPU`] when the worker did not say).
    pub cpu: String,
    /// First epoch of the span (the checkpoint it resumed from).
    pub from: u32,
    /// The epoch it ends at: where the next attempt resumed, or the cell's epochs done.
    pub to: u32,
}

/// The spans of a cell's `epochs_done` epochs that each CPU trained, from its attempts in
/// the order they started. An attempt's epochs count up to where the next kept attempt
/// resumed from: epochs trained after an attempt's last checkpoint were lost with it and
/// trained again. Read from the last attempt backwards, an attempt that resumed at or after
/// the point a later one resumed from kept nothing. Neighbouring spans on one CPU merge.
pub fn cpu_spans(attempts: &[AttemptCpu], epochs_done: u32) -> Vec<CpuSpan> {
    let mut end = epochs_done;
    let mut spans = Vec::new();
    for a in attempts.iter().rev() {
        if a.resumed_from < end {
            spans.push(CpuSpan {
                cpu: if a.cpu.trim().is_empty() {
                    UNRECORDED_CPU.to_string()
                } else {
                    a.cpu.trim().to_string()
                },
                from: a.resumed_from,
                to: end,
            });
            end = a.resumed_from;
        }
    }
    spans.reverse();
    let mut merged: Vec<CpuSpan> = Vec::with_capacity(spans.len());
    for s in spans {
        match merged.last_mut() {
            Some(last) if last.cpu == s.cpu && last.to == s.from => last.to = s.to,
            _ => merged.push(s),
        }
    }
    merged
}

/// A cell's spans as text: `AMD EPYC` on one CPU, `AMD EPYC 0-517 · Intel Xeon 517-1200`
/// on several.
pub fn spans_text(spans: &[CpuSpan]) -> String {
    match spans {
        [one] => one.cpu.clone(),
        _ => spans
            .iter()
            .map(|s| format!("{} {}\u{2013}{}", s.cpu, s.from, s.to))
            .collect::<Vec<_>>()
            .join(" \u{b7} "),
    }
}

/// The sweep's CPUs in one sentence: how many cells each trained (in full or in part) and
/// how many cells more than one trained, pointing to the cell table for each CPU's epochs
/// when `with_table`; `None` when no cell has trained.
pub fn summary(cells: &[ReportCell], with_table: bool) -> Option<String> {
    let mut count: BTreeMap<&str, usize> = BTreeMap::new();
    let mut mixed = 0;
    for c in cells.iter().filter(|c| !c.trained_on.is_empty()) {
        let mut cpus: Vec<&str> = c.trained_on.iter().map(|s| s.cpu.as_str()).collect();
        cpus.sort_unstable();
        cpus.dedup();
        if cpus.len() > 1 {
            mixed += 1;
        }
        for cpu in cpus {
            *count.entry(cpu).or_default() += 1;
        }
    }
    if count.is_empty() {
        return None;
    }
    let list: Vec<String> = count
        .iter()
        .map(|(cpu, n)| format!("{cpu}: {n} cell{}", if *n == 1 { "" } else { "s" }))
        .collect();
    let mut s = format!("Trained on {}.", list.join("; "));
    if mixed > 0 {
        s.push_str(&format!(
            " {mixed} cell{} trained on more than one CPU{}.",
            if mixed == 1 { "" } else { "s" },
            if with_table {
                " (the table gives each CPU's epochs)"
            } else {
                ""
            }
        ));
    }
    Some(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn a(cpu: &str, from: u32) -> AttemptCpu {
        AttemptCpu {
            cpu: cpu.into(),
            resumed_from: from,
        }
    }

    fn span(cpu: &str, from: u32, to: u32) -> CpuSpan {
        CpuSpan {
            cpu: cpu.into(),
            from,
            to,
        }
    }

    #[test]
    fn one_machine_is_one_span() {
        assert_eq!(
            cpu_spans(&[a("amd", 0), a("amd", 220)], 1200),
            vec![span("amd", 0, 1200)]
        );
        assert_eq!(spans_text(&cpu_spans(&[a("amd", 0)], 10)), "amd");
    }

    #[test]
    fn a_cell_that_moved_names_both_with_their_epochs() {
        let s = cpu_spans(&[a("amd", 0), a("amd", 220), a("intel", 517)], 1200);
        assert_eq!(s, vec![span("amd", 0, 517), span("intel", 517, 1200)]);
        assert_eq!(
            spans_text(&s),
            "amd 0\u{2013}517 \u{b7} intel 517\u{2013}1200"
        );
    }

    #[test]
    fn an_attempt_whose_epochs_were_trained_again_kept_none() {
        // intel's attempt from 500 was lost (no checkpoint after it): amd trained on from 400
        let s = cpu_spans(&[a("amd", 0), a("intel", 500), a("amd", 400)], 900);
        assert_eq!(s, vec![span("amd", 0, 900)]);
        // a lost attempt that started fresh again
        let s = cpu_spans(&[a("intel", 0), a("amd", 0)], 50);
        assert_eq!(s, vec![span("amd", 0, 50)]);
    }

    #[test]
    fn unrecorded_cpus_and_untrained_cells() {
        assert_eq!(
            cpu_spans(&[a("", 0), a("amd", 816)], 1200),
            vec![span(UNRECORDED_CPU, 0, 816), span("amd", 816, 1200)]
        );
        assert!(cpu_spans(&[a("amd", 0)], 0).is_empty());
        assert!(cpu_spans(&[], 100).is_empty());
    }
}
