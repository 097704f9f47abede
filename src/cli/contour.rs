//! `truecut contour FILE --machine ID|FILE.json`: contour error of a G-code program (Zhang & Chen
//! 2025), computed locally by the motion core (no server needed).

use std::path::PathBuf;

use anyhow::{Context, bail};

use crate::motion::gcode::{ReadOptions, parse_modes};
use crate::motion::{DEFAULT_PERIOD_S, predict_program_settled};

/// Predict the contour error of a G-code program on a machine (interpolation with RTCP,
/// servo cascade per axis, distance of the simulated tool tip to the commanded path).
///
/// The machine is either a JSON file with the body of `PUT /v1/machines/{id}` (when the
/// argument names an existing file) or the id of a machine stored in the service's data
/// (`--data-dir` / `--database-url`, the same as `truecut serve`).
#[derive(Debug, clap::Args)]
pub struct Args {
    /// G-code file (ISO 6983 / Fanuc subset; G43.4/G49 and TRAORI/TRAFOOF for RTCP). Read
    /// leniently: words that do not move an axis (T, M, S, comments, G43 H, G54..G59, ...)
    /// are passed through and printed once each as warnings.
    pub file: PathBuf,
    /// Refuse every word the lenient reading would pass with a warning (as the route's
    /// `"strict": true`).
    #[arg(long)]
    pub strict: bool,
    /// Machine: path to a machine-definition JSON file, or the id of a stored machine.
    #[arg(long)]
    pub machine: String,
    /// Interpolation period, s.
    #[arg(long, default_value_t = DEFAULT_PERIOD_S)]
    pub period_s: f64,
    /// Most interpolation periods to simulate.
    #[arg(long, default_value_t = 10_000_000)]
    pub max_periods: usize,
    /// Write the full answer (the JSON of POST /v1/machines/{id}/contour-error) to this file.
    #[arg(long)]
    pub output: Option<PathBuf>,
    /// Data directory holding stored machines (used when --machine is an id).
    #[arg(long, default_value = "./truecut-data", env = "TRUECUT_DATA_DIR")]
    pub data_dir: PathBuf,
    /// Database URL (postgres://...) holding stored machines; default: SQLite in --data-dir.
    #[arg(long, env = "DATABASE_URL")]
    pub database_url: Option<String>,
}

fn load_machine(args: &Args) -> anyhow::Result<(String, serde_json::Value)> {
    let path = PathBuf::from(&args.machine);
    if path.is_file() {
        let text = std::fs::read_to_string(&path)
            .with_context(|| format!("reading machine file {}", path.display()))?;
        let def = serde_json::from_str(&text)
            .with_context(|| format!("machine file {} is not valid JSON", path.display()))?;
        return Ok((args.machine.clone(), def));
    }
    // The service's id rule, so a typo is not looked up in the store.
    if !crate::store::is_valid_id(&args.machine) {
        let shown: String = args.machine.chars().take(80).collect();
        bail!(
            "--machine '{}' is neither an existing JSON file nor a valid machine id: machine id \
             '{shown}' is invalid: use 1 to 64 characters from A-Z a-z 0-9 . _ - (and not '.' or '..')",
            args.machine
        );
    }
    if args.database_url.is_none() && !args.data_dir.is_dir() {
        bail!(
            "--machine '{}' is not a file, and the data dir {} does not exist: give a machine \
             JSON file or the --data-dir of the service that stores it",
            args.machine,
            args.data_dir.display()
        );
    }
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?;
    let def = runtime.block_on(async {
        let store = crate::store::Store::open(&args.data_dir, args.database_url.as_deref()).await?;
        store.get_machine(&args.machine).await
    })?;
    match def {
        Some(d) => Ok((args.machine.clone(), d)),
        None => bail!(
            "machine '{}' is not stored in {} (or the database): give a machine JSON file, \
             or PUT /v1/machines/{} first",
            args.machine,
            args.data_dir.display(),
            args.machine
        ),
    }
}

/// Runs the prediction and prints a summary (and writes `--output`).
pub fn run(args: Args) -> anyhow::Result<()> {
    crate::motion::check_period(args.period_s)?;
    let gcode = std::fs::read_to_string(&args.file)
        .with_context(|| format!("reading G-code file {}", args.file.display()))?;
    let (id, def) = load_machine(&args)?;
    let def = crate::motion::stored_definition(&id, &def)?;
    let machine = crate::motion::machine_for_simulation(&id, &def)?;
    let options = ReadOptions {
        strict: args.strict,
        ..ReadOptions::default()
    };
    let at_file = |e: crate::motion::Error| anyhow::anyhow!("{}: {e}", args.file.display());
    let (mut program, control, mut warnings) = parse_modes(&gcode, &options).map_err(at_file)?;
    if !options.strict {
        let has = |name: &str| machine.axes.iter().any(|a| a.name == name);
        warnings.extend(program.forget_still_rotary_axes(has("A"), has("C")));
    }
    for w in &warnings {
        eprintln!("warning: {}: {w}", args.file.display());
    }
    let (p, settle) = predict_program_settled(
        &machine,
        &program,
        &control,
        args.period_s,
        args.max_periods,
    )
    .map_err(at_file)?;
    let r = &p.report;
    let n = p.commanded.t.len();
    let worst = (0..n).fold(0, |b, i| {
        if r.contour_error[i] > r.contour_error[b] {
            i
        } else {
            b
        }
    });
    println!(
        "{}: {:.3} s of machining, {n} periods of {} s",
        args.file.display(),
        settle.command_end_s,
        args.period_s
    );
    println!(
        "run-out: the tool was {:.4} mm from the end point when the command ended; simulated \
         {:.3} s more{}",
        settle.lag_at_command_end_mm,
        settle.settle_s,
        if settle.settled {
            " until it was within 0.1 um"
        } else {
            ""
        }
    );
    if let Some(w) = settle.warning() {
        eprintln!("warning: {}: {w}", args.file.display());
    }
    println!(
        "contour error: max {:.4} mm at t = {:.3} s (line {}), rms {:.4} mm",
        r.max, p.commanded.t[worst], p.commanded.line[worst], r.rms
    );
    for (k, ax) in machine.axes.iter().enumerate() {
        let unit = if k >= 3 { "deg" } else { "mm" };
        println!(
            "tracking error {}: max {:.4} {unit}, rms {:.4} {unit}",
            ax.name, r.tracking_max[k], r.tracking_rms[k]
        );
    }
    if let Some(o) = r.orientation_max_deg {
        println!("tool orientation error: max {o:.4} deg");
    }
    if let Some(out) = &args.output {
        let bytes = crate::wire::contour::encode_answer_with_warnings(
            &machine,
            &p,
            &warnings,
            Some(&settle),
        )?;
        std::fs::write(out, bytes).with_context(|| format!("writing {}", out.display()))?;
        println!("full answer written to {}", out.display());
    }
    Ok(())
}
