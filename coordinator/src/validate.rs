//! Checks of what workers report before anything is stored: pure functions over the report
//! and the numbers of its cell, unit-tested without a database. A refused report is an
//! `INVALID_ARGUMENT` that names the field and the value.

use crate::{Error, Result};
use gaitsweep_model::GaitScore;
use std::collections::BTreeMap;

/// Every component of a gait score must be a finite number: an infinite score would be
/// promoted over every real one, a NaN one cannot be ranked.
pub fn score(s: &GaitScore) -> Result<()> {
    let levels = s.levels.iter().map(|l| (Some(l.level), &l.score));
    for (level, g) in std::iter::once((None, s)).chain(levels) {
        if let Some((name, v)) = g.components().into_iter().find(|(_, v)| !v.is_finite()) {
            let at = level.map(|l| format!("levels[{l}].")).unwrap_or_default();
            return Err(Error::BadRequest(format!(
                "score.{at}{name} is {v}: every score component must be a finite number (the evaluation produced a non-finite value; the cell should be failed instead)"
            )));
        }
        if let Some(l) = level.filter(|l| *l > 9) {
            return Err(Error::BadRequest(format!(
                "score.levels has level {l}: difficulty levels run from 0 to 9"
            )));
        }
    }
    Ok(())
}

/// Epoch numbers run from 1 to the cell's epochs.
fn epoch(what: &str, epoch: u32, total: u32) -> Result<()> {
    if epoch == 0 || epoch > total {
        return Err(Error::BadRequest(format!(
            "{what} epoch {epoch} is out of range: this cell trains epochs 1 to {total}"
        )));
    }
    Ok(())
}

/// Epoch metrics: epochs within the cell's range, every value finite.
pub fn progress(total: u32, epochs: &[(u32, BTreeMap<String, f64>)]) -> Result<()> {
    for (e, values) in epochs {
        epoch("progress", *e, total)?;
        if let Some((name, v)) = values.iter().find(|(_, v)| !v.is_finite()) {
            return Err(Error::BadRequest(format!(
                "metric {name:?} of epoch {e} is {v}: metrics must be finite numbers"
            )));
        }
    }
    Ok(())
}

/// The epochs a result was trained for.
pub fn result_epochs(total: u32, epochs: u32) -> Result<()> {
    epoch("result", epochs, total)
}

/// A checkpoint's epoch (0 is allowed: a checkpoint of the untrained policy).
pub fn checkpoint_epoch(total: u32, e: u32) -> Result<()> {
    if e > total {
        return Err(Error::BadRequest(format!(
            "checkpoint epoch {e} is out of range: this cell trains epochs 1 to {total}"
        )));
    }
    Ok(())
}

/// A lease asks for one of the slots the worker registered.
pub fn slot(slot: u32, slots: u32) -> Result<()> {
    if slot >= slots.max(1) {
        return Err(Error::BadRequest(format!(
            "slot {slot} is out of range: this worker registered {} slot(s), numbered from 0",
            slots.max(1)
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn good() -> GaitScore {
        GaitScore {
            score: 0.5,
            track: 0.5,
            effort: 0.1,
            tilt: 0.0,
            progress: 0.0,
            fall_rate: 0.0,
            mean_vel_error: 0.1,
            mean_abs_torque: 3.0,
            cost_of_transport: 1.0,
            robots: 2,
            ..Default::default()
        }
    }

    #[test]
    fn non_finite_scores_are_refused_by_name() {
        assert!(score(&good()).is_ok());
        for bad in [f64::INFINITY, f64::NEG_INFINITY, f64::NAN] {
            let mut s = good();
            s.score = bad;
            assert!(score(&s).unwrap_err().to_string().contains("score.score"));
            let mut s = good();
            s.cost_of_transport = bad;
            assert!(score(&s)
                .unwrap_err()
                .to_string()
                .contains("cost_of_transport"));
        }
    }

    #[test]
    fn epochs_outside_the_cell_are_refused() {
        let m = |v: f64| BTreeMap::from([("kl".to_string(), v)]);
        assert!(progress(20, &[(1, m(0.1)), (20, m(0.2))]).is_ok());
        assert!(progress(20, &[(0, m(0.1))]).is_err());
        assert!(progress(20, &[(u32::MAX, m(0.1))]).is_err());
        assert!(progress(20, &[(3, m(f64::INFINITY))]).is_err());
        assert!(progress(20, &[(3, m(f64::NAN))]).is_err());
        assert!(result_epochs(20, 20).is_ok());
        assert!(result_epochs(20, 21).is_err());
        assert!(result_epochs(20, 0).is_err());
        assert!(checkpoint_epoch(20, 0).is_ok());
        assert!(checkpoint_epoch(20, 21).is_err());
    }

    #[test]
    fn slots_are_numbered_from_zero() {
        assert!(slot(0, 1).is_ok());
        assert!(slot(1, 2).is_ok());
        assert!(slot(2, 2).is_err());
        assert!(slot(4_000_000_000, 4).is_err());
    }
}
