//! A sweep's budget and evaluation in words, and the names of grid points, for the report.

use super::plots::fmt_w;
use super::ReportData;

/// The budget a sweep was given, in words: robots and epochs per cell, how the search spends
/// them, where a cell never rewarded stops, replicates, the evaluation rollout and any PPO overrides.
pub fn budget_text(spec: &gaitsweep_core::ResolvedSpec) -> String {
    let search = gaitsweep_search::describe(spec).budget;
    let ppo = if spec.ppo_overrides.is_empty() {
        String::new()
    } else {
        let o: Vec<String> = spec
            .ppo_overrides
            .iter()
            .map(|(k, v)| format!("{k} = {v}"))
            .collect();
        format!("; PPO overrides: {}", o.join(", "))
    };
    let finalists = spec.finalists.map_or(String::new(), |f| {
        format!(
            ", then the top {} points of each terrain {} seeds each (finalists; the promoted point is the finalist with the best mean)",
            f.top, f.seeds
        )
    });
    let stop = match spec.stop_unrewarded {
        Some(f) => format!(
            "; except a cell whose mean reward was 0 at every epoch, stopped and scored at epoch {} by stop_unrewarded = {f}",
            spec.stop_unrewarded_after()
        ),
        None => String::new(),
    };
    format!(
        "{} robots per cell, up to {} PPO epochs per cell ({search}{stop}), {} seed{} per grid point{finalists}; \
         evaluation: {}{ppo}",
        spec.agents_per_cell,
        spec.epochs,
        spec.replicates,
        if spec.replicates == 1 { "" } else { "s" },
        eval_text(spec),
    )
}

/// What a sweep's score measures, in words: the rollout, the levels per terrain and the
/// progress term.
pub fn eval_text(spec: &gaitsweep_core::ResolvedSpec) -> String {
    let levels: Vec<String> = spec
        .terrains
        .iter()
        .map(|t| {
            let l = spec.eval_levels_for(&t.to_string());
            let l: Vec<String> = l.iter().map(u8::to_string).collect();
            format!(
                "{t} at level{} {}",
                if l.len() == 1 { "" } else { "s" },
                l.join(", ")
            )
        })
        .collect();
    format!(
        "deterministic policy, {} robots x {} s at each level, {}; the score is the mean over the levels; \
         progress term: {}",
        spec.eval.robots,
        spec.eval.seconds,
        levels.join("; "),
        match spec.eval.score {
            gaitsweep_model::ScoreVariant::Eq4 => "Eq. 4's (sum of squared step displacements)",
            gaitsweep_model::ScoreVariant::Bounded =>
                "bounded (each step's displacement capped at its commanded distance)",
        }
    )
}

/// Names of grid points, "(w1, w2)" each, comma-separated; "none" for no point.
pub(super) fn point_names(d: &ReportData, points: &[(usize, usize)]) -> String {
    if points.is_empty() {
        return "none".to_string();
    }
    points
        .iter()
        .map(|&(i, j)| format!("({}, {})", fmt_w(d.w1_values[i]), fmt_w(d.w2_values[j])))
        .collect::<Vec<_>>()
        .join(", ")
}

/// "1 degree of freedom", "n degrees of freedom".
pub(super) fn dof_text(dof: usize) -> String {
    format!("{dof} degree{} of freedom", if dof == 1 { "" } else { "s" })
}
