//! The demo's report: the operator's networked report, plus what only a run with the telerobot
//! daemon and the shim in the same process knows — the telerobot's summary (its loop timing, the
//! uplink's latency, quinn's counts on its side) and the shim's release lateness.

use std::fmt::Write as _;

use operator::report::{NetworkedReport, PeerFigures};
use serde::Serialize;

/// Everything the demo reports. Serialised flat: the operator report's keys, then `telerobot`
/// and `shim`.
#[derive(Clone, Debug, Serialize)]
pub struct DemoReport {
    /// The operator app's report.
    #[serde(flatten)]
    pub run: NetworkedReport,
    /// The telerobot daemon's summary.
    pub telerobot: telerobot::Summary,
    /// The netem shim's figures (absent when the demo connects directly).
    pub shim: Option<ShimReport>,
}

/// The netem shim's figures.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct ShimReport {
    /// Release lateness (actual − due send time), both directions.
    pub lateness: rt::Summary,
    /// Datagrams forwarded up (operator → telerobot) and down.
    pub forwarded: (u64, u64),
    /// Datagrams dropped by the link model (loss, queue limit), up and down.
    pub dropped: (u64, u64),
}

impl From<&netem::ShimStats> for ShimReport {
    fn from(s: &netem::ShimStats) -> Self {
        ShimReport {
            lateness: s.lateness,
            forwarded: (s.up.forwarded, s.down.forwarded),
            dropped: (
                s.up.dropped_loss + s.up.dropped_limit,
                s.down.dropped_loss + s.down.dropped_limit,
            ),
        }
    }
}

impl DemoReport {
    /// The telerobot's and the shim's figures, for the operator table's rows that need them.
    pub fn peer_figures(&self) -> PeerFigures {
        PeerFigures {
            telerobot_link: Some(self.telerobot.link),
            uplink_latency: Some(self.telerobot.command_latency),
            telerobot_timing: Some(self.telerobot.timing),
            shim_lateness: self.shim.map(|s| s.lateness),
            telerobot_camera: Some([
                self.telerobot.camera_frames,
                self.telerobot.camera_over_budget,
            ]),
            played_lag_ms: self.telerobot.last.node.mean_played_lag_ms(),
        }
    }
}

/// The stdout table: the operator's, with the telerobot's and the shim's rows.
pub fn table(r: &DemoReport) -> String {
    operator::report::table(&r.run, &r.peer_figures())
}

/// The files of `--out DIR`: `report.json` (every figure of [`DemoReport`]), `series.csv`, and the
/// force, error and spectrum plots as SVG and PNG (drawn by `lab`, as `mmt experiment` draws
/// them).
pub fn files(
    r: &DemoReport,
    s: &metrics::Series,
) -> Result<Vec<(String, Vec<u8>)>, lab::plot::PlotError> {
    let mut files = lab::report::files(&r.run.experiment, s)?;
    let json =
        serde_json::to_vec_pretty(r).map_err(|e| lab::plot::PlotError::Draw(e.to_string()))?;
    for (name, bytes) in &mut files {
        if name == "report.json" {
            bytes.clone_from(&json);
        }
    }
    Ok(files)
}

/// The one-line banner printed before a demo run.
pub fn banner(delay_ms: f64, seconds: f64, via_shim: bool, seed: u64) -> String {
    let link = if via_shim {
        format!("netem shim ({delay_ms} ms each way)")
    } else {
        "direct".to_owned()
    };
    let mut out = String::new();
    let _ = write!(
        out,
        "demo: telerobot (exp-1 scene, seed {seed}) ⇄ {link} ⇄ operator (scripted:exp1), {seconds} s over loopback QUIC…"
    );
    out
}
