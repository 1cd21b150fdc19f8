//! The `operator` commands behind the thin `main.rs`: argument types (clap) and one function per
//! subcommand, writing to a caller-given output so they are tested without a terminal.
//!
//! - `operator devices` — what this machine offers: recognised HID devices, whether the Force
//!   Dimension SDK loads and which devices it sees, and what each backend can and cannot do.
//!   Works with no device and no SDK (says so, exits 0).
//! - `operator gen-cert --out DIR` — writes `DIR/operator.crt` and `DIR/operator.key`.
//! - `operator run --device SPEC --connect ADDR --identity DIR --trust TELEROBOT_CRT [--seconds S]
//!   [--position-scale F] [--device-origin X,Y,Z] [--out DIR] [--json]` — runs the operator app ([`crate::app`]) and prints its report; without
//!   the network flags it only opens the device and says what it is (exits 0: a device check).
//!
//! Not here: logging and Ctrl-C set-up (main), anything of the haptic loop.

use std::fmt::Write as _;
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use clap::{Args, Parser, Subcommand};
use rt::Shutdown;

pub use net::{GenCertArgs, NetArgs, NetArgsError, gen_cert};
pub use ros::{RosArgs, RosArgsError};
pub use run::{LoopArgs, PriorArgs, RtArgs, emit};

use crate::device::omega::{self, OmegaConfig, SdkProbe, sdk};
use crate::device::spacemouse::{self, HidEntry, SpaceMouseConfig, report::KNOWN_DEVICES};
use crate::device::{
    DeviceCapabilities, DeviceError, DeviceSpec, ManagedConfig, OpenOptions, open_device,
};
use crate::safety::SafetyConfig;

/// Operator side of the model-mediated teleoperation system.
#[derive(Debug, Parser)]
#[command(name = "operator", version, about)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// List the haptic devices and backends this machine offers.
    Devices(DevicesArgs),
    /// Run the operator app against a telerobot: haptic loop, network, report.
    Run(Box<RunArgs>),
    /// Make the operator's certificate and key (DIR/operator.crt, DIR/operator.key).
    GenCert(GenCertArgs),
}

/// Force Dimension SDK options.
#[derive(Clone, Debug, Args)]
pub struct SdkArgs {
    /// Force Dimension SDK library to load (overrides MMT_FD_SDK_LIB; default libdhd.so from the
    /// loader's search path).
    #[arg(long, value_name = "PATH")]
    pub fd_sdk_lib: Option<PathBuf>,
    /// Omega hardware watchdog [ms], 0.125 to 31.875: forces go off when commands stop this long.
    #[arg(long, value_name = "MS", default_value_t = 20.0)]
    pub fd_watchdog_ms: f64,
    /// Omega velocity-guard threshold to set (SDK units, > 0); default: keep the factory value.
    #[arg(long, value_name = "N")]
    pub fd_velocity_threshold: Option<u32>,
}

impl SdkArgs {
    fn config(&self) -> Result<OmegaConfig, DeviceError> {
        let ms = self.fd_watchdog_ms;
        let watchdog =
            Duration::try_from_secs_f64(ms / 1000.0).map_err(|_| DeviceError::InvalidConfig {
                field: "--fd-watchdog-ms",
                value: ms.to_string(),
                expected: "0.125 to 31.875 ms",
            })?;
        omega::watchdog_units(watchdog)?;
        Ok(OmegaConfig {
            library: self.fd_sdk_lib.clone(),
            watchdog,
            velocity_threshold: self.fd_velocity_threshold,
        })
    }
}

/// `operator devices` options.
#[derive(Clone, Debug, Args)]
#[command(allow_negative_numbers = true)]
pub struct DevicesArgs {
    /// SDK options.
    #[command(flatten)]
    pub sdk: SdkArgs,
}

/// `operator run` options. Negative numbers are values (`--seconds -1` is refused by the range
/// check, as `--seconds=-1` is, not taken for a flag).
#[derive(Clone, Debug, Args)]
#[command(allow_negative_numbers = true)]
pub struct RunArgs {
    /// The device: scripted:NAME, replay:FILE.csv, replay:FILE.mcap (a recording), spacemouse,
    /// omega (Force Dimension SDK) or ros2 (a driver on a ROS 2 graph: forcedimension_ros2's
    /// topics by default).
    #[arg(long, value_name = "SPEC")]
    pub device: DeviceSpec,
    /// Time over which force ramps in after enabling [ms].
    #[arg(long, value_name = "MS", default_value_t = 200)]
    pub enable_ramp_ms: u64,
    /// SpaceMouse speed at full deflection [m/s].
    #[arg(long, value_name = "M_PER_S", default_value_t = 0.1)]
    pub spacemouse_speed: f64,
    /// Commanded metres per device metre (translation only; > 0, at most 20). Below 1 the tool moves less
    /// than the hand, for fine work; the device's clutch button repositions the hand.
    #[arg(long, value_name = "F", default_value_t = 1.0)]
    pub position_scale: f64,
    /// Where the device's origin (the centre of its workspace) sits in the telerobot's world,
    /// `X,Y,Z` [m]: commanded = origin + scale · device position. Default 0,0,0 (the scripted
    /// and replay devices already move in world coordinates).
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_origin, allow_hyphen_values = true)]
    pub device_origin: Option<[f64; 3]>,
    /// SDK options.
    #[command(flatten)]
    pub sdk: SdkArgs,
    /// ROS 2 device options.
    #[command(flatten)]
    pub ros: RosArgs,
    /// Network options.
    #[command(flatten)]
    pub net: NetArgs,
    /// Run length, loop and report options.
    #[command(flatten)]
    pub run: LoopArgs,
}

/// Why `operator run`'s options are refused.
#[derive(Debug, thiserror::Error)]
pub enum RunArgsError {
    /// `--position-scale` zero, negative, not finite or above 20.
    #[error(
        "--position-scale {0}: expected a finite number > 0 and at most 20 (commanded metres per \
         device metre; 1 = one-to-one)"
    )]
    PositionScale(f64),
}

impl RunArgs {
    /// The safety settings these options give.
    pub fn safety(&self) -> Result<SafetyConfig, RunArgsError> {
        let scale = self.position_scale;
        if crate::safety::PositionScale::new(scale).is_err() {
            return Err(RunArgsError::PositionScale(scale));
        }
        Ok(SafetyConfig {
            position_scale: scale,
            device_origin_m: self.device_origin.unwrap_or_default(),
            ..SafetyConfig::default()
        })
    }
}

/// `--device-origin X,Y,Z`: three finite coordinates within ±10 m.
fn parse_origin(s: &str) -> Result<[f64; 3], String> {
    let expected =
        || format!("`{s}`: expected X,Y,Z, three finite coordinates in metres within ±10 m");
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    let [x, y, z] = parts.as_slice() else {
        return Err(expected());
    };
    let mut out = [0.0; 3];
    for (slot, part) in out.iter_mut().zip([x, y, z]) {
        *slot = part
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite() && v.abs() <= 10.0)
            .ok_or_else(expected)?;
    }
    Ok(out)
}

/// `operator devices`: prints what this machine offers. Always succeeds unless output fails.
pub fn devices(args: &DevicesArgs, out: &mut dyn Write) -> anyhow::Result<()> {
    let hid = spacemouse::list_hid();
    let probe = match args.sdk.config() {
        Ok(cfg) => omega::probe(&cfg, std::env::var_os(sdk::ENV_VAR)),
        Err(e) => SdkProbe {
            library: Err(e),
            devices: Vec::new(),
        },
    };
    out.write_all(render_devices(&hid, &probe).as_bytes())?;
    Ok(())
}

/// The `devices` report as text.
#[must_use]
pub fn render_devices(hid: &Result<(Vec<HidEntry>, usize), DeviceError>, sdk: &SdkProbe) -> String {
    let mut s = String::new();
    // Writing to a String cannot fail.
    let _ = render_into(&mut s, hid, sdk);
    s
}

fn render_into(
    s: &mut String,
    hid: &Result<(Vec<HidEntry>, usize), DeviceError>,
    probe: &SdkProbe,
) -> std::fmt::Result {
    render_hid(s, hid)?;
    let force_device = render_sdk(s, probe)?;
    render_backends(s)?;
    let spacemouse_seen = matches!(hid, Ok((list, _)) if !list.is_empty());
    writeln!(s)?;
    if force_device {
        writeln!(s, "A force-feedback device is available: --device omega")?;
    } else if spacemouse_seen {
        writeln!(
            s,
            "No force-feedback device found. A SpaceMouse is available as position input only (--device spacemouse)."
        )?;
    } else {
        writeln!(
            s,
            "No haptic device found on this machine. Use --device scripted:NAME or replay:FILE.csv (simulated, no force felt)."
        )?;
    }
    Ok(())
}

/// The HID section: the SpaceMouse-family devices recognised.
fn render_hid(
    s: &mut String,
    hid: &Result<(Vec<HidEntry>, usize), DeviceError>,
) -> std::fmt::Result {
    writeln!(s, "HID devices (SpaceMouse family, vendors 046d and 256f):")?;
    match hid {
        Err(e) => writeln!(s, "  cannot enumerate HID devices: {e}")?,
        Ok((list, total)) if list.is_empty() => writeln!(
            s,
            "  none recognised ({total} HID device(s) present; {} known ids)",
            KNOWN_DEVICES.len()
        )?,
        Ok((list, _)) => {
            for d in list {
                writeln!(
                    s,
                    "  {:04x}:{:04x}  {}  \"{}\"  {}",
                    d.vendor_id,
                    d.product_id,
                    d.model,
                    d.product.as_deref().unwrap_or("?"),
                    d.path
                )?;
            }
        }
    }
    Ok(())
}

/// The Force Dimension SDK section; whether it found a force-feedback device.
fn render_sdk(s: &mut String, probe: &SdkProbe) -> Result<bool, std::fmt::Error> {
    writeln!(s, "\nForce Dimension SDK:")?;
    let mut force_device = false;
    match &probe.library {
        Err(e) => writeln!(s, "  not available: {e}")?,
        Ok(path) => {
            writeln!(s, "  loaded {path}")?;
            if probe.devices.is_empty() {
                writeln!(s, "  no device connected")?;
            }
            for (i, d) in probe.devices.iter().enumerate() {
                match d {
                    Ok(name) => {
                        force_device = true;
                        writeln!(s, "  device {i}: {name}")?;
                    }
                    Err(e) => writeln!(s, "  device {i}: {e}")?,
                }
            }
        }
    }
    Ok(force_device)
}

/// The backends table: what each `--device` offers.
fn render_backends(s: &mut String) -> std::fmt::Result {
    writeln!(s, "\nBackends:")?;
    writeln!(
        s,
        "  {:<15} {:<14} {:>9} {:>13} {:>13} {:<20} notes",
        "--device", "force output", "max force", "max stiffness", "max damping", "workspace"
    )?;
    let omega = DeviceCapabilities::omega7("omega");
    let sm = SpaceMouseConfig::default();
    let rows = [
        (
            "scripted:NAME",
            "no (recorded)",
            Some(&omega),
            omega.workspace,
            "omega.7 twin following a script; forces recorded, felt by no one",
        ),
        (
            "replay:FILE.csv",
            "no (recorded)",
            Some(&omega),
            omega.workspace,
            "omega.7 twin replaying a recording (t_s,x,y,z[,vx,vy,vz])",
        ),
        (
            "spacemouse",
            "NO",
            None,
            sm.workspace,
            "velocity input integrated to a bounded position; no force feedback at all",
        ),
        (
            "omega",
            "yes",
            Some(&omega),
            omega.workspace,
            "needs the Force Dimension SDK (libdhd.so) and a connected omega.x",
        ),
        (
            "ros2",
            "yes",
            Some(&omega),
            omega.workspace,
            "a driver on a ROS 2 graph (forcedimension_ros2's topics by default; no ROS install here)",
        ),
    ];
    for (name, force, caps, ws, note) in rows {
        let (f, k, b) = caps.map_or(("-".into(), "-".into(), "-".into()), |c| {
            (
                format!("{} N", c.max_force_n),
                format!("{} N/m", c.max_stiffness_n_per_m),
                format!("{} N·s/m", c.max_damping_n_s_per_m),
            )
        });
        writeln!(
            s,
            "  {name:<15} {force:<14} {f:>9} {k:>13} {b:>13} {:<20} {note}",
            ws.describe()
        )?;
    }
    Ok(())
}

/// `operator run`: with the network flags, runs the operator app ([`crate::app::run`]) until
/// `--seconds` or `shutdown` and prints the report; without them, opens the device, says what it
/// is and stops (a device check: success when the device opened). `--out` is created and
/// checked first, before anything else can take time.
pub fn run(args: &RunArgs, shutdown: Shutdown, out: &mut dyn Write) -> anyhow::Result<ExitCode> {
    let dir = args
        .run
        .out
        .as_deref()
        .map(rt::OutDir::prepare)
        .transpose()?;
    let safety = args.safety()?;
    // Every flag is checked before anything is printed or opened (issue 11: a range error came
    // after the "network:" line), also when no telerobot is given.
    args.run.periodic()?;
    args.run.prior.node_config()?;
    let net = args.net.config()?;
    let options = OpenOptions {
        scripted_length_s: args.run.seconds,
        managed: ManagedConfig {
            enable_ramp: Duration::from_millis(args.enable_ramp_ms),
            ..ManagedConfig::default()
        },
        spacemouse: SpaceMouseConfig {
            max_speed_m_per_s: args.spacemouse_speed,
            ..SpaceMouseConfig::default()
        },
        omega: args.sdk.config()?,
        ros: args.ros.options(&args.device)?,
    };
    let Some(net) = net else {
        let device = open_device(&args.device, &options)?;
        let spec = device.spec();
        writeln!(
            out,
            "device {}: {} — max force {} N, workspace {}",
            args.device,
            spec.name,
            spec.max_force_n,
            spec.workspace.describe()
        )?;
        writeln!(out, "{}", force_line(&args.device, spec))?;
        writeln!(
            out,
            "operator run: no telerobot given (--connect, --identity, --trust); device opened and closed again."
        )?;
        return Ok(ExitCode::SUCCESS);
    };
    let line = format!(
        "network: telerobot {} pinned to {}, as '{}'",
        net.connect, net.telerobot_cert_source, net.operator_name
    );
    // With --json, stdout is the report alone (it must parse as JSON): the line goes to stderr.
    if args.run.json {
        eprintln!("{line}");
    } else {
        writeln!(out, "{line}")?;
    }
    run::run_cmd(
        &args.run,
        dir,
        net,
        (args.device.clone(), options),
        safety,
        shutdown,
        out,
    )?;
    Ok(ExitCode::SUCCESS)
}

/// The warning printed when the device gives no force feedback.
#[must_use]
pub fn no_force_warning(spec: &DeviceSpec) -> String {
    match spec {
        DeviceSpec::SpaceMouse => "the SpaceMouse has NO force output: you will feel nothing. It only moves the tool (velocity input integrated to a position).".into(),
        DeviceSpec::Ros2 => "ros2 with --topic command=none: NO force is written; the device is position input only.".into(),
        other => format!("{other} is simulated: forces are recorded but felt by no one."),
    }
}

/// The start message's word on forces: plainly whether a run writes them to this device.
#[must_use]
pub fn force_line(spec: &DeviceSpec, caps: &DeviceCapabilities) -> String {
    match spec {
        _ if !caps.outputs_force => format!("WARNING: {}", no_force_warning(spec)),
        DeviceSpec::Ros2 => "forces: WRITTEN in a run — published on the command topic above \
            while the device's poses are fresh (zero otherwise, and nothing before the first \
            pose), ramped in, through the safety layer"
            .into(),
        _ => "forces: WRITTEN to the device in a run, ramped in, through the safety layer".into(),
    }
}

mod net;
mod ros;
mod run;
#[cfg(test)]
mod tests;
