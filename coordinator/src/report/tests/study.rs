//! `coordinator findings`: several sweeps' findings in one table, and where each is read from.

use super::super::findings::{markdown, study_markdown};
use super::super::study::{parse_source, Source, SWEEP_ID_FILE};
use super::*;

/// The cells of a table row after the label and the paper's.
fn row_cells(md: &str, label: &str) -> Vec<String> {
    let line = md
        .lines()
        .find(|l| l.starts_with(&format!("| {label}")))
        .unwrap_or_else(|| panic!("no row {label:?} in\n{md}"));
    // Escaped bars (\|) stay inside their cell.
    let cells: Vec<String> = line
        .replace("\\|", "\u{1}")
        .split('|')
        .map(|c| c.trim().replace('\u{1}', "\\|"))
        .collect();
    cells[3..cells.len() - 1].to_vec()
}

#[test]
fn a_study_puts_every_robots_terrains_side_by_side() {
    let anymal = synthetic();
    let mut heavy = synthetic();
    heavy.robot = "heavy".into();
    heavy.sweep_id = 2;
    heavy.name = "a \"heavy\"\nstudy".into();
    // The heavy robot on one terrain only: its w1 = 12 row falls everywhere.
    heavy.terrains.truncate(1);
    heavy.cells.retain(|c| c.terrain_index == 0);
    for c in heavy.cells.iter_mut().filter(|c| c.w1 == 12.0) {
        if let Some(s) = c.score.as_mut() {
            s.fall_rate = 0.5;
        }
    }
    let md = study_markdown(&[
        ("studies/recordings/anymal".into(), anymal.clone()),
        ("/tmp/heavy".into(), heavy.clone()),
    ]);
    assert!(
        md.contains("from 2 sweeps, one column per robot and terrain"),
        "{md}"
    );
    assert!(
        md.contains("- anymal: sweep 7 \"synthetic\" read from studies/recordings/anymal (state: running). Budget: 64 robots per cell. Trained on amd: "),
        "each sweep says where it was read from and its machines: {md}"
    );
    assert!(
        md.contains("- heavy: sweep 2 \"a 'heavy' study\" read from /tmp/heavy"),
        "{md}"
    );
    assert!(
        md.contains("| | the paper (Kim et al. 2024) | anymal flat | anymal rough | heavy flat |\n|---|---|---|---|---|\n"),
        "{md}"
    );
    // Each column reads as in its own sweep's findings.md.
    let own_anymal = markdown(&anymal).unwrap();
    let own_heavy = markdown(&heavy).unwrap();
    for label in [
        "cells scored",
        "best point",
        "the best point's gait",
        "where the best",
        "steps between",
        "largest step",
        "rows of w1 standing",
        "points not told apart",
        "cells that walk",
        "points never rewarded",
    ] {
        let mut own = row_cells(&own_anymal, label);
        own.extend(row_cells(&own_heavy, label));
        assert_eq!(row_cells(&md, label), own, "row {label:?}");
    }
    assert_eq!(
        row_cells(&md, "cells that walk"),
        vec![
            "4 of 11 (4 at every level)",
            "3 of 10 (3 at every level)",
            "0 of 11 (0 at every level)"
        ],
        "the heavy column is the heavy sweep's"
    );
    // The overlap across terrains, per robot with more than one terrain.
    let items: Vec<&str> = own_anymal
        .lines()
        .filter(|l| l.starts_with("- points") || l.starts_with("- the weights"))
        .collect();
    assert_eq!(items.len(), 3, "{own_anymal}");
    assert!(
        md.contains(&format!("- anymal:\n  {}\n", items.join("\n  "))),
        "the overlap reads as in the sweep's own findings: {md}"
    );
    assert!(
        !md.contains("- heavy:\n"),
        "one terrain has no overlap: {md}"
    );
}

#[test]
fn a_source_names_its_sweep_or_says_how() {
    assert_eq!(
        parse_source("/data/x:12").unwrap(),
        Source {
            data_dir: "/data/x".into(),
            sweep: 12
        }
    );
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().to_str().unwrap();
    let err = parse_source(d).unwrap_err().to_string();
    assert!(
        err.contains("names no sweep: write it as DATA_DIR:SWEEP_ID"),
        "{err}"
    );
    std::fs::write(dir.path().join(SWEEP_ID_FILE), "3\n").unwrap();
    assert_eq!(parse_source(d).unwrap().sweep, 3, "a recording's sweep.id");
    std::fs::write(dir.path().join(SWEEP_ID_FILE), "three").unwrap();
    let err = parse_source(d).unwrap_err().to_string();
    assert!(
        err.contains("should hold a sweep id (a whole number) but reads \"three\""),
        "{err}"
    );
}
