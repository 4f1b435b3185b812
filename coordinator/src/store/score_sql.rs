//! The score's columns in SQL, built from the one list of its components
//! ([`GaitScore::components`]), so that the tables that store a score (`scores`,
//! `evaluations`, `level_scores`) are written from one place.

use gaitsweep_model::GaitScore;
use sqlx::any::AnyArguments;
use sqlx::query::Query;
use sqlx::Any;

/// Components only a cell's final score (`scores`) stores.
const FINAL_ONLY: [&str; 2] = ["mean_abs_torque", "cost_of_transport"];

/// Which of a score's components a table stores.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum ScoreTable {
    /// `scores`: every component.
    Final,
    /// `evaluations` and `level_scores`: all but [`FINAL_ONLY`].
    Evaluation,
}

impl ScoreTable {
    /// The component columns of this table, in bind order (`robots` follows them).
    pub(super) fn fields(self) -> Vec<&'static str> {
        GaitScore::default()
            .components()
            .into_iter()
            .map(|(k, _)| k)
            .filter(|k| self == ScoreTable::Final || !FINAL_ONLY.contains(k))
            .collect()
    }

    /// `score, track, ..., robots`.
    pub(super) fn columns(self) -> String {
        let mut f = self.fields();
        f.push("robots");
        f.join(", ")
    }

    /// `$first, ..., $last` for [`ScoreTable::columns`].
    pub(super) fn placeholders(self, first: usize) -> String {
        (first..first + self.fields().len() + 1)
            .map(|i| format!("${i}"))
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// `score = excluded.score, ..., robots = excluded.robots`, for an upsert.
    pub(super) fn upserts(self) -> String {
        let mut f = self.fields();
        f.push("robots");
        f.iter()
            .map(|k| format!("{k} = excluded.{k}"))
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// Binds `s`'s components and robots in the order of [`ScoreTable::columns`].
    pub(super) fn bind<'q>(
        self,
        mut q: Query<'q, Any, AnyArguments<'q>>,
        s: &GaitScore,
    ) -> Query<'q, Any, AnyArguments<'q>> {
        for (k, v) in s.components() {
            if self == ScoreTable::Final || !FINAL_ONLY.contains(&k) {
                q = q.bind(v);
            }
        }
        q.bind(s.robots as i64)
    }

    /// Binds components read by name (`None`: not known, stored as NULL) and robots in the
    /// order of [`ScoreTable::columns`]: a periodic evaluation's metrics from older workers
    /// may lack some.
    pub(super) fn bind_by_name<'q>(
        self,
        mut q: Query<'q, Any, AnyArguments<'q>>,
        get: impl Fn(&str) -> Option<f64>,
    ) -> Query<'q, Any, AnyArguments<'q>> {
        for k in self.fields() {
            q = q.bind(get(k));
        }
        q.bind(get("robots").map(|r| r as i64))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn columns_placeholders_and_upserts_line_up() {
        let e = ScoreTable::Evaluation;
        assert_eq!(
            e.columns(),
            "score, track, effort, tilt, progress, progress_bounded, fall_rate, mean_vel_error, \
             mean_speed, overspeed, robots"
        );
        assert_eq!(
            e.placeholders(5),
            "$5, $6, $7, $8, $9, $10, $11, $12, $13, $14, $15"
        );
        assert!(e
            .upserts()
            .ends_with("overspeed = excluded.overspeed, robots = excluded.robots"));
        let f = ScoreTable::Final;
        assert_eq!(f.fields().len(), 12);
        assert!(f.columns().contains("cost_of_transport, robots"));
    }
}
