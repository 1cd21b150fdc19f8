//! The experiment report as people read it on stdout: this run's figures next to the thesis's.
//! `mmt experiment` and the networked operator app print the same table.

use std::fmt::Write;

use mmt::model::backsolve::Confidence;

use crate::{ExperimentReport, ParameterReport};

/// The stdout table: this run's figures next to the thesis's.
pub fn table(r: &ExperimentReport) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{} on scene {} — trajectory {}, {:.0} s simulated, seed {}, one-way delay {} ms",
        r.experiment, r.scene, r.trajectory, r.sim_seconds, r.seed, r.delay_ms
    );
    let _ = writeln!(out, "{:<46} {:>14}   thesis", "", "this run");
    error_rows(&mut out, r);
    timing_rows(&mut out, r);
    for p in &r.parameters {
        parameter_lines(&mut out, p);
    }
    for e in &r.estimators {
        if let Some(chosen) = e.stats.selected {
            let _ = writeln!(
                out,
                "structure chosen from the data, {}: {} ({} changes)",
                e.axes,
                chosen.describe(),
                e.stats.structure_changes
            );
        }
    }
    if !r.left_out.is_empty() {
        let _ = writeln!(out, "left out: {}", r.left_out.join("; "));
    }
    out
}

/// One row: name, this run's value, the thesis's.
fn row(out: &mut String, name: &str, value: String, thesis: &str) {
    let _ = writeln!(out, "{name:<46} {value:>14}   {thesis}");
}

fn pct(v: Option<f64>) -> String {
    v.map_or("—".to_string(), |v| format!("{v:.2} %"))
}

fn sec(v: Option<f64>) -> String {
    v.map_or("never".to_string(), |v| format!("{v:.2} s"))
}

fn ms(v: Option<f64>) -> String {
    v.map_or("—".to_string(), |v| format!("{v:.1} ms"))
}

/// The rendered force's RMS errors: overall, after stable (with the tangential axis, the
/// true force and each band), and with remote-only contact.
fn error_rows(out: &mut String, r: &ExperimentReport) {
    row(
        out,
        "RMS error, from first contact",
        pct(r.rms_error_pct),
        "—",
    );
    row(
        out,
        "RMS error, once a model is rendered",
        pct(r.rms_error_pct_after_stable),
        "~30 % low freq., up to 100 % high",
    );
    row(
        out,
        "  tangential axis (the thesis's y) only",
        pct(r.tangential_rms_error_pct_after_stable),
        "",
    );
    if r.rms_error_pct_after_stable_vs_true_force.is_some() {
        row(
            out,
            "  against the true force (no sensor noise, bias)",
            pct(r.rms_error_pct_after_stable_vs_true_force),
            "",
        );
    }
    for b in &r.bands {
        row(
            out,
            &format!("  band {:.1}–{:.1} Hz", b.lo_hz, b.hi_hz),
            pct(b.rms_error_pct),
            if b.hi_hz <= 0.3 {
                "< 0.25 N, ~30 %"
            } else {
                "~1 N plateau, up to 100 %"
            },
        );
    }
    row(
        out,
        "RMS error with remote-only contact (thesis way)",
        pct(r.rms_error_pct_remote_contact),
        "",
    );
}

/// What was rendered before the first model, and the error of each stage.
fn prior_rows(out: &mut String, r: &ExperimentReport) {
    let prior = match r.prior {
        Some(p) => format!(
            "normal {:.0} N/m, {:.1} N·s/m ({})",
            p.normal.k_n_per_m,
            p.normal.b_ns_per_m,
            p.source.label()
        ),
        None => "none: free space until the first model".to_owned(),
    };
    row(out, "prior rendered before the first model", prior, "");
    let g = &r.stage_errors;
    let stage = |pct: Option<f64>, s: f64| match pct {
        Some(p) => format!("{p:.1} % ({s:.2} s)"),
        None => "—".to_owned(),
    };
    let stages = format!(
        "{} / {} / {}",
        stage(g.prior_pct, g.seconds[0]),
        stage(g.reduced_pct, g.seconds[1]),
        stage(g.whole_pct, g.seconds[2])
    );
    row(
        out,
        "error in contact: prior / reduced / whole model",
        stages,
        "",
    );
    // The telerobot's first fit of each Kelvin–Voigt group, after its onset.
    let first: Vec<String> = r
        .estimators
        .iter()
        .map(|e| match (e.stats.first_fit_after_s, e.stats.first_fits) {
            (Some(s), n) => match (e.stats.contact_fits, e.stats.whole_fit_after_s) {
                (0, _) => format!("{} {s:.2} s ({n} sent)", e.axes),
                (_, Some(w)) => format!("{} {s:.2} s, every term {w:.2} s ({n} sent)", e.axes),
                (_, None) => format!("{} {s:.2} s, every term — ({n} sent)", e.axes),
            },
            (None, _) => format!("{} —", e.axes),
        })
        .collect();
    row(out, "first fit after contact", first.join(", "), "");
}

/// How soon things happen: stable parameters, rendering, the estimator's fit, and the contact
/// switch latencies.
fn timing_rows(out: &mut String, r: &ExperimentReport) {
    row(
        out,
        "time to stable parameters",
        sec(r.time_to_stable_s),
        "16.1 s (exp 2)",
    );
    row(
        out,
        "rendering starts after first contact",
        sec(r.render_start_s),
        "",
    );
    row(
        out,
        "first force after local contact",
        ms(r.first_force_after_local_contact_ms),
        "",
    );
    row(
        out,
        "error settles within 10 % (250 ms windows)",
        sec(r.settle_s),
        "",
    );
    row(
        out,
        "error in the 1 s after each re-contact",
        pct(r.recontact_error_pct),
        "",
    );
    prior_rows(out, r);
    row(
        out,
        "estimator reconstruction error",
        pct(r.reconstruction_error_pct),
        "~5 % (exp 2)",
    );
    let l = &r.contact_switch_latency_ms;
    let missed = match l.local_missed {
        0 => String::new(),
        n => format!(" ({n} of {} switches not followed within 3 s)", l.switches),
    };
    row(
        out,
        "contact switch latency, operator-side detection",
        format!("{}{missed}", ms(l.local)),
        "—",
    );
    row(
        out,
        "contact switch latency, remote state only",
        ms(l.remote_only),
        &format!(
            "a round trip ({:.0} ms)",
            r.thesis.contact_switch_latency_ms
        ),
    );
}

/// One set's estimated parameters against the truth, and the back-solve's confidence in them.
fn parameter_lines(out: &mut String, p: &ParameterReport) {
    let values: Vec<String> = p
        .values
        .iter()
        .map(|(name, truth, est, err)| {
            if err.is_finite() {
                format!("{name} {est:.4} ({truth}, {err:+.1} %)")
            } else {
                format!("{name} {est:.4} ({truth})")
            }
        })
        .collect();
    let _ = writeln!(out, "parameters, {}: {}", p.axes, values.join(", "));
    let confidence = match p.confidence {
        Confidence::Identified => "identified",
        Confidence::Low { .. } => "LOW, parameter errors amplified",
    };
    let updates = match (p.low_confidence_updates, p.confirmed_updates) {
        (Some(low), Some(all)) => format!(", {low} of {all} confirmed sets low-confidence"),
        _ => String::new(),
    };
    let _ = writeln!(
        out,
        "back-solve confidence, {}: {confidence} (condition {:.1}){updates}",
        p.axes, p.condition
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{NodeInfo, RunInfo, Series, analyse};

    /// Before: after an outage the table said "time to stable: never" next to "after the
    /// parameters are stable 50.3 %": the figure is from when a model is first rendered.
    #[test]
    fn the_error_once_a_model_is_rendered_does_not_claim_stable_parameters() {
        let info = RunInfo {
            experiment: "networked".into(),
            scene: "exp1".into(),
            left_out: vec![],
            trajectory: "scripted".into(),
            seed: 0,
            delay_ms: 0.0,
        };
        let mut r = analyse(&info, &Series::default(), NodeInfo::default());
        r.time_to_stable_s = None;
        r.rms_error_pct_after_stable = Some(50.3);
        let t = table(&r);
        assert!(
            t.lines()
                .any(|l| l.starts_with("time to stable") && l.contains("never"))
        );
        let line = t.lines().find(|l| l.contains("50.30 %")).unwrap();
        assert!(!line.contains("stable"), "{line}");
    }
}
