//! `netem`: the UDP link-emulation shim's command line. Parses and validates the flags, installs
//! the Ctrl-C handler, calls [`netem::shim::run`] and prints the counters on exit.

use std::net::{SocketAddr, ToSocketAddrs};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::{Context, anyhow, bail};
use clap::{Arg, ArgMatches, Command};
use netem::model::PROFILES;
use netem::units::{parse_duration_ns, parse_percent, parse_rate_bit_per_s};
use netem::{Direction, Distribution, LinkConfig, Loss, ShimConfig};

/// One link setting: its flag for both directions, then its `--up-` and `--down-` overrides.
struct Knob {
    flags: [&'static str; 3],
    value: &'static str,
    help: &'static str,
}

macro_rules! knob {
    ($name:literal, $value:literal, $help:literal) => {
        Knob {
            flags: [$name, concat!("up-", $name), concat!("down-", $name)],
            value: $value,
            help: $help,
        }
    };
}

const KNOBS: &[Knob] = &[
    knob!(
        "profile",
        "NAME",
        "Start from a named profile: lan, wifi, 4g, satellite, thesis-400ms"
    ),
    knob!(
        "delay",
        "TIME",
        "One-way base delay, e.g. 400ms, 250us, 1.5s [default: 0]"
    ),
    knob!(
        "jitter",
        "TIME",
        "Jitter: half-width (uniform) or σ (tables) [default: 0]"
    ),
    knob!(
        "correlation",
        "PERCENT",
        "Correlation of successive jitter draws (netem's smoothing; shrinks the jitter) [default: 0%]"
    ),
    knob!(
        "distribution",
        "NAME|FILE",
        "Jitter shape: uniform, normal, pareto, paretonormal, or a netem .dist file [default: uniform]"
    ),
    knob!(
        "order",
        "keep|free",
        "keep: jitter never reorders (due = max(due, previous due)); free: netem's tfifo, jitter reorders [default: keep]"
    ),
    knob!("loss", "PERCENT", "Random (Bernoulli) loss, e.g. 1%"),
    knob!(
        "loss-ge",
        "P[,R[,1-H[,1-K]]]",
        "Gilbert-Elliott loss (netem gemodel), percentages; defaults R=100%, 1-H=100%, 1-K=0%"
    ),
    knob!(
        "duplicate",
        "PERCENT",
        "Send this share of packets twice [default: 0%]"
    ),
    knob!(
        "reorder",
        "PERCENT",
        "Send this share of packets at once, ahead of delayed ones; needs --delay [default: 0%]"
    ),
    knob!(
        "gap",
        "N",
        "Reorder only after N-1 packets were delayed (netem gap) [default: 1]"
    ),
    knob!(
        "rate",
        "RATE",
        "Link rate in bits/s, e.g. 10mbit, 512kbit [default: unlimited]"
    ),
    knob!(
        "overhead",
        "BYTES",
        "Bytes added to each datagram for --rate (may be negative) [default: 28, IPv4+UDP]"
    ),
    knob!(
        "limit",
        "PACKETS",
        "Queue limit; more packets in flight are dropped [default: 100000]"
    ),
];

const AFTER_HELP: &str = "\
Directions: up = from the client (the most recent sender to --listen) towards --forward;
down = from --forward back to the client. One client at a time.

Per-direction overrides: every link flag above also exists as --up-FLAG and --down-FLAG
(e.g. --up-delay 400ms --down-delay 20ms, --down-loss 5%, --up-profile 4g). The override beats
the flag for both directions, which beats the profile. --loss and --loss-ge are one setting:
the most specific one given wins; giving both at the same level is an error.

Units: times ns, us (µs), ms, s (400ms, 2us, 1.5s); rates bit, kbit, mbit, gbit (powers of 1000);
percentages need the % sign (1%, 0.5%).

Order: by default jitter keeps packet order, as netem with a pfifo child: reordering jitter makes
QUIC declare spurious losses. --order free gives netem's own behaviour.

On Ctrl-C (or SIGTERM) the shim stops, prints its counters and release lateness, and exits.
The --log CSV has one row per packet copy: dir,packet,seq,len,arrival_ns,due_ns,release_ns,fate
(ns since the shim's start); it is the ground truth of the delay each packet was given.";

static STOP: AtomicBool = AtomicBool::new(false);

fn main() -> ExitCode {
    match try_main() {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("netem: {}", rt::exit::message(error.as_ref()));
            ExitCode::from(2)
        }
    }
}

fn try_main() -> anyhow::Result<()> {
    let matches = command().get_matches();
    let config = shim_config(&matches)?;
    install_signal_handlers().context("cannot install the Ctrl-C handler")?;
    eprintln!(
        "netem: {} -> {}  up: {}  down: {}  (seed {}, Ctrl-C to stop)",
        config.listen, config.forward, config.up, config.down, config.seed
    );
    let stats = netem::shim::run(config, &STOP)?;
    println!("{stats}");
    Ok(())
}

fn command() -> Command {
    let mut command = Command::new("netem")
        .about("UDP link emulator: delay, jitter, loss, duplication, reordering and rate between a client and a server, per direction, with netem's semantics")
        .after_help(AFTER_HELP)
        .arg(Arg::new("listen").long("listen").value_name("ADDR").required(true).help("Address the client sends to, e.g. 127.0.0.1:4434"))
        .arg(Arg::new("forward").long("forward").value_name("ADDR").required(true).help("Address packets from the client go to, e.g. 127.0.0.1:4433"))
        .arg(Arg::new("seed").long("seed").allow_hyphen_values(true).value_name("N").help("Seed of the links' random draws; the same seed gives the same fates [default: 0]"))
        .arg(Arg::new("log").long("log").value_name("FILE.csv").help("Write one CSV row per packet (see below)"))
        .arg(Arg::new("spin").long("spin").allow_hyphen_values(true).value_name("TIME").help("Busy-spin this long before each release for µs accuracy; 0 = sleep only [default: 200us]"))
        .arg(Arg::new("rt-priority").long("rt-priority").allow_hyphen_values(true).value_name("1-99").help("Run the scheduler thread under SCHED_FIFO at this priority (needs CAP_SYS_NICE); bounds the lateness tail on a loaded machine [default: off]"));
    for knob in KNOBS {
        let [flag, up, down] = knob.flags;
        command = command.arg(
            Arg::new(flag)
                .long(flag)
                .value_name(knob.value)
                .help(knob.help)
                .allow_hyphen_values(true)
                .help_heading("Link (both directions; --up-FLAG / --down-FLAG override)"),
        );
        for name in [up, down] {
            command = command.arg(
                Arg::new(name)
                    .long(name)
                    .value_name(knob.value)
                    .allow_hyphen_values(true)
                    .hide(true),
            );
        }
    }
    command
}

fn shim_config(m: &ArgMatches) -> anyhow::Result<ShimConfig> {
    let listen = address(m, "listen")?;
    let forward = address(m, "forward")?;
    let mut config = ShimConfig::new(listen, forward);
    config.up = link_config(m, Direction::Up)?;
    config.down = link_config(m, Direction::Down)?;
    if let Some(seed) = m.get_one::<String>("seed") {
        config.seed = seed.parse().map_err(|_| {
            anyhow!("--seed: `{seed}` is not a seed: expected an integer 0..=18446744073709551615")
        })?;
    }
    if let Some(spin) = m.get_one::<String>("spin") {
        config.spin_window_ns = parse_duration_ns(spin).context("--spin")?;
    }
    if let Some(v) = m.get_one::<String>("rt-priority") {
        config.realtime_priority =
            Some(integer(("rt-priority", v), "a priority: expected 1..=99")?);
    }
    config.log_path = m.get_one::<String>("log").map(PathBuf::from);
    Ok(config)
}

fn address(m: &ArgMatches, flag: &str) -> anyhow::Result<SocketAddr> {
    let text = m
        .get_one::<String>(flag)
        .map(String::as_str)
        .unwrap_or_default();
    text.to_socket_addrs()
        .ok()
        .and_then(|mut addrs| addrs.next())
        .ok_or_else(|| anyhow!("--{flag}: `{text}` is not an address: expected HOST:PORT, e.g. 127.0.0.1:4433 or [::1]:4433"))
}

/// The value of a knob for `direction` and the flag it came from: the override, else the flag
/// for both directions.
fn lookup<'m>(
    m: &'m ArgMatches,
    direction: Direction,
    name: &str,
) -> Option<(&'static str, &'m str)> {
    let knob = KNOBS.iter().find(|k| k.flags[0] == name)?;
    let [flag, up, down] = knob.flags;
    let specific = match direction {
        Direction::Up => up,
        Direction::Down => down,
    };
    [specific, flag]
        .into_iter()
        .find_map(|f| m.get_one::<String>(f).map(|v| (f, v.as_str())))
}

fn link_config(m: &ArgMatches, direction: Direction) -> anyhow::Result<LinkConfig> {
    let get = |name: &str| lookup(m, direction, name);
    let mut c = match get("profile") {
        Some((flag, name)) => LinkConfig::profile(name).ok_or_else(|| {
            let names: Vec<&str> = PROFILES.iter().map(|(n, _)| *n).collect();
            anyhow!(
                "--{flag}: `{name}` is not a profile: expected one of {}",
                names.join(", ")
            )
        })?,
        None => LinkConfig::default(),
    };
    delay_settings(&mut c, get)?;
    if let Some(loss) = loss_setting(m, direction)? {
        c.loss = loss;
    }
    duplicate_and_reorder_settings(&mut c, get)?;
    rate_settings(&mut c, get)?;
    c.validate().map_err(|e| {
        let flag = match e.field {
            "delay_ns" => "delay",
            "jitter_ns" => "jitter",
            "jitter_correlation" => "correlation",
            "duplicate_probability" => "duplicate",
            "reorder_probability" => "reorder",
            "reorder_gap" => "gap",
            "rate_bit_per_s" => "rate",
            "overhead_bytes" => "overhead",
            "limit_packets" => "limit",
            _ => "loss-ge",
        };
        anyhow!("{direction} link (--{flag} / --{direction}-{flag}): {e}")
    })?;
    Ok(c)
}

/// `--delay`, `--jitter`, `--correlation`, `--distribution` and `--order` as `get` finds them.
fn delay_settings<'m>(
    c: &mut LinkConfig,
    get: impl Fn(&str) -> Option<(&'static str, &'m str)>,
) -> anyhow::Result<()> {
    if let Some(v) = get("delay") {
        c.delay_ns = duration(v)?;
    }
    if let Some(v) = get("jitter") {
        c.jitter_ns = duration(v)?;
    }
    if let Some(v) = get("correlation") {
        c.jitter_correlation = percent(v)?;
    }
    if let Some((flag, v)) = get("distribution") {
        c.distribution = Distribution::from_name_or_path(v).with_context(|| format!("--{flag}"))?;
        if c.jitter_ns == 0 {
            bail!(
                "--{flag} `{v}` shapes the jitter, but the jitter is 0: give --jitter too \
                 (tc netem refuses a distribution without one)"
            );
        }
    }
    if let Some((flag, v)) = get("order") {
        c.keep_order = match v {
            "keep" => true,
            "free" => false,
            _ => bail!("--{flag}: `{v}` is not an order: expected keep or free"),
        };
    }
    Ok(())
}

/// `--duplicate`, `--reorder` and `--gap` as `get` finds them.
fn duplicate_and_reorder_settings<'m>(
    c: &mut LinkConfig,
    get: impl Fn(&str) -> Option<(&'static str, &'m str)>,
) -> anyhow::Result<()> {
    if let Some(v) = get("duplicate") {
        c.duplicate_probability = percent(v)?;
    }
    if let Some(v) = get("reorder") {
        c.reorder_probability = percent(v)?;
    }
    if let Some(v) = get("gap") {
        c.reorder_gap = integer(v, "a gap: expected an integer 1..=4294967295")?;
    }
    Ok(())
}

/// `--rate`, `--overhead` and `--limit` as `get` finds them.
fn rate_settings<'m>(
    c: &mut LinkConfig,
    get: impl Fn(&str) -> Option<(&'static str, &'m str)>,
) -> anyhow::Result<()> {
    if let Some((flag, v)) = get("rate") {
        c.rate_bit_per_s = Some(parse_rate_bit_per_s(v).with_context(|| format!("--{flag}"))?);
    }
    if let Some(v) = get("overhead") {
        c.overhead_bytes = integer(
            v,
            "an overhead: expected an integer number of bytes, -65535..=65535",
        )?;
    }
    if let Some(v) = get("limit") {
        c.limit_packets = integer(
            v,
            "a limit: expected an integer number of packets, 1..=10000000",
        )?;
    }
    Ok(())
}

/// A duration flag value [ns].
fn duration((flag, v): (&str, &str)) -> anyhow::Result<u64> {
    parse_duration_ns(v).with_context(|| format!("--{flag}"))
}

/// A percentage flag value, as a fraction.
fn percent((flag, v): (&str, &str)) -> anyhow::Result<f64> {
    parse_percent(v).with_context(|| format!("--{flag}"))
}

/// An integer flag value; `expected` completes "`VALUE` is not …".
fn integer<T: std::str::FromStr>((flag, v): (&str, &str), expected: &str) -> anyhow::Result<T> {
    v.parse()
        .map_err(|_| anyhow!("--{flag}: `{v}` is not {expected}"))
}

/// `--loss` / `--loss-ge` for `direction`: the most specific level wins.
fn loss_setting(m: &ArgMatches, direction: Direction) -> anyhow::Result<Option<Loss>> {
    let prefix = match direction {
        Direction::Up => "up-",
        Direction::Down => "down-",
    };
    for level in [prefix, ""] {
        let random_flag = format!("{level}loss");
        let ge_flag = format!("{level}loss-ge");
        let random = m.get_one::<String>(&random_flag);
        let ge = m.get_one::<String>(&ge_flag);
        match (random, ge) {
            (Some(_), Some(_)) => {
                bail!("--{random_flag} and --{ge_flag}: give one loss model, not both")
            }
            (Some(v), None) => {
                let probability = parse_percent(v).with_context(|| format!("--{random_flag}"))?;
                return Ok(Some(Loss::Random { probability }));
            }
            (None, Some(v)) => {
                return parse_gemodel(v)
                    .with_context(|| format!("--{ge_flag}"))
                    .map(Some);
            }
            (None, None) => {}
        }
    }
    Ok(None)
}

/// `P[,R[,1-H[,1-K]]]` with tc's defaults R = 100 %, 1−H = 100 %, 1−K = 0 %.
fn parse_gemodel(text: &str) -> anyhow::Result<Loss> {
    let values = text
        .split(',')
        .map(parse_percent)
        .collect::<Result<Vec<f64>, _>>()?;
    let (p, r, one_minus_h, one_minus_k) = match values.as_slice() {
        [p] => (*p, 1.0, 1.0, 0.0),
        [p, r] => (*p, *r, 1.0, 0.0),
        [p, r, h] => (*p, *r, *h, 0.0),
        [p, r, h, k] => (*p, *r, *h, *k),
        _ => bail!(
            "`{text}` has {} values: expected 1 to 4 percentages P,R,1-H,1-K",
            values.len()
        ),
    };
    Ok(Loss::GilbertElliott {
        p,
        r,
        one_minus_h,
        one_minus_k,
    })
}

extern "C" fn on_signal(_signal: libc::c_int) {
    STOP.store(true, Ordering::SeqCst);
}

#[allow(unsafe_code)]
fn install_signal_handlers() -> std::io::Result<()> {
    let handler: extern "C" fn(libc::c_int) = on_signal;
    for signal in [libc::SIGINT, libc::SIGTERM] {
        // SAFETY: `on_signal` is an `extern "C"` function whose only action is an atomic store,
        // which is async-signal-safe; SIGINT and SIGTERM have no handler the Rust runtime needs.
        let previous = unsafe { libc::signal(signal, handler as libc::sighandler_t) };
        if previous == libc::SIG_ERR {
            return Err(std::io::Error::last_os_error());
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(args: &[&str]) -> anyhow::Result<ShimConfig> {
        let mut argv = vec![
            "netem",
            "--listen",
            "127.0.0.1:0",
            "--forward",
            "127.0.0.1:9",
        ];
        argv.extend_from_slice(args);
        shim_config(&command().try_get_matches_from(argv)?)
    }

    /// Issue 11: `--delay -5ms` gave clap's "unexpected argument" while `--delay=-5ms` gave
    /// the value's error; both forms now give the value's error.
    #[test]
    fn a_negative_value_is_checked_in_both_forms() {
        for (flag, value) in [
            ("--delay", "-5ms"),
            ("--up-delay", "-5ms"),
            ("--jitter", "-1ms"),
            ("--loss", "-1%"),
            ("--rate", "-5mbit"),
            ("--spin", "-1us"),
            ("--seed", "-1"),
            ("--rt-priority", "-1"),
        ] {
            let joined = format!("{flag}={value}");
            let spaced = parse(&[flag, value]).unwrap_err();
            let equals = parse(&[&joined]).unwrap_err();
            let (spaced, equals) = (format!("{spaced:#}"), format!("{equals:#}"));
            assert_eq!(spaced, equals, "{flag}");
            assert!(spaced.contains(flag) && spaced.contains(value), "{spaced}");
        }
    }

    #[test]
    fn both_directions_with_overrides() {
        let c = parse(&[
            "--delay",
            "400ms",
            "--down-delay",
            "20ms",
            "--loss",
            "1%",
            "--up-loss-ge",
            "1%,30%",
            "--seed",
            "7",
        ])
        .unwrap();
        assert_eq!(c.up.delay_ns, 400_000_000);
        assert_eq!(c.down.delay_ns, 20_000_000);
        assert_eq!(c.down.loss, Loss::Random { probability: 0.01 });
        assert_eq!(
            c.up.loss,
            Loss::GilbertElliott {
                p: 0.01,
                r: 0.3,
                one_minus_h: 1.0,
                one_minus_k: 0.0
            }
        );
        assert_eq!(c.seed, 7);
    }

    #[test]
    fn profile_then_flags() {
        let c = parse(&[
            "--profile",
            "satellite",
            "--down-loss",
            "0%",
            "--up-order",
            "free",
        ])
        .unwrap();
        assert_eq!(c.up.delay_ns, 300_000_000);
        assert_eq!(c.up.loss, Loss::Random { probability: 0.01 });
        assert_eq!(c.down.loss, Loss::Random { probability: 0.0 });
        assert!(!c.up.keep_order && c.down.keep_order);
        let c = parse(&["--rate", "10mbit", "--down-overhead", "-14"]).unwrap();
        assert_eq!((c.up.overhead_bytes, c.down.overhead_bytes), (28, -14));
    }

    #[test]
    fn errors_name_the_flag_the_value_and_what_was_expected() {
        let message = |args: &[&str]| format!("{:#}", parse(args).unwrap_err());
        let m = message(&["--delay", "10ms", "--distribution", "normal"]);
        assert!(
            m.contains("--distribution `normal`") && m.contains("--jitter"),
            "{m}"
        );
        assert!(parse(&["--jitter", "2ms", "--distribution", "normal"]).is_ok());
        let m = message(&["--up-delay", "40"]);
        assert!(
            m.contains("--up-delay") && m.contains("`40`") && m.contains("400ms"),
            "{m}"
        );
        let m = message(&["--rate", "10mbps"]);
        assert!(
            m.contains("--rate") && m.contains("bytes per second"),
            "{m}"
        );
        let m = message(&["--reorder", "5%"]);
        assert!(
            m.contains("--reorder") && m.contains("needs a delay"),
            "{m}"
        );
        let m = message(&["--loss", "1%", "--loss-ge", "1%"]);
        assert!(m.contains("not both"), "{m}");
        let m = message(&["--loss-ge", "1%,2%,3%,4%,5%"]);
        assert!(m.contains("expected 1 to 4"), "{m}");
        let m = message(&["--profile", "dialup"]);
        assert!(m.contains("lan, wifi"), "{m}");
        let m = message(&["--jitter", "3s"]);
        assert!(m.contains("--jitter") && m.contains("2147483647"), "{m}");
        let m = message(&["--gap", "-3", "--reorder", "1%", "--delay", "1ms"]);
        assert!(m.contains("--gap") && m.contains("`-3`"), "{m}");
        let m = message(&["--limit", "0"]);
        assert!(m.contains("--limit") && m.contains("1..=10000000"), "{m}");
    }
}
