//! `truecut iso230-2 FILE` and `truecut iso230-4 FILE`: ISO 230-2 and ISO 230-4 evaluations of
//! measurement files, locally by the metrology core or (with `--server`) by a running
//! service, which can also store an ISO 230-2 run per machine axis and simulate a circular
//! test. Figures are printed in µm; `--json` prints the route's answer instead.

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use reqwest::Method;

use super::client::{Client, ServerArgs};
use crate::metrology::{
    PositionTable, PositioningTrace, TraceOptions, circular_hysteresis, evaluate_circle,
    evaluate_table, evaluate_trace,
};
use crate::wire::iso230::{
    Iso2302Answer, Iso2302Request, Iso2304Answer, Iso2304Request, TraceBody,
};

/// ISO 230-2:2014 positioning accuracy and repeatability of an axis.
///
/// FILE is the route's JSON body, or CSV: a table `target,direction,measured` (one row per
/// approach, direction `fwd`/`+` or `bwd`/`-`, rows of a target in cycle order), or a logged
/// run `commanded,measured` (with a `t` column or `--period-s`). Positions in mm.
#[derive(Debug, clap::Args)]
#[command(after_help = "Example:\n  truecut iso230-2 x_axis.csv\n  \
    truecut iso230-2 --server http://127.0.0.1:8080 laser_log.csv --period-s 0.01\n  \
    truecut iso230-2 --server http://127.0.0.1:8080 --machine m1 --axis X --label 'after compensation' x_axis.csv")]
pub struct Args2 {
    /// The measurement file (.csv or .json).
    pub file: PathBuf,
    /// Evaluate on this running service instead of locally (see also --token).
    #[arg(long, env = "TRUECUT_SERVER")]
    pub server: Option<String>,
    /// Bearer token for --server.
    #[arg(long, env = "TRUECUT_TOKEN", hide_env_values = true)]
    pub token: Option<String>,
    /// Store the run under this machine (with --axis; needs --server).
    #[arg(long, requires_all = ["axis", "server"])]
    pub machine: Option<String>,
    /// Machine axis of the stored run (X, Y, Z, A, B, C, U, V, W).
    #[arg(long, requires = "machine")]
    pub axis: Option<String>,
    /// Label of the stored run (e.g. "before compensation").
    #[arg(long, requires = "machine")]
    pub label: Option<String>,
    /// Sampling period of a logged run without a `t` column, s.
    #[arg(long)]
    pub period_s: Option<f64>,
    /// Logged run: the measured position has settled while it moves slower than this, mm/s
    /// (default 0.01).
    #[arg(long)]
    pub settle_speed_mm_s: Option<f64>,
    /// Logged run: ... for at least this long, s (default 0.3).
    #[arg(long)]
    pub min_settled_s: Option<f64>,
    /// Print the answer JSON instead of the table.
    #[arg(long)]
    pub json: bool,
}

/// ISO 230-4:2005 circular test: G, F_max, F_min about the orthogonal least-squares circle,
/// and the hysteresis H with a reverse run.
///
/// FILE is CSV `x,y` (mm, one row per point) or the route's JSON body. With `--simulate`
/// the service predicts the test on a stored machine's servo model instead (no FILE).
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Example:\n  truecut iso230-4 ccw.csv --radius 50 --reverse cw.csv\n  \
    truecut iso230-4 --server http://127.0.0.1:8080 --simulate demo --radius 50 --feed 2000"
)]
pub struct Args4 {
    /// The points file (.csv `x,y` or .json); not with --simulate.
    #[arg(required_unless_present = "simulate")]
    pub file: Option<PathBuf>,
    /// Nominal radius, mm.
    #[arg(long)]
    pub radius: Option<f64>,
    /// Fixed centre `x,y`, mm (default: the least-squares circle's).
    #[arg(long, value_parser = parse_pair, allow_hyphen_values = true)]
    pub centre: Option<[f64; 2]>,
    /// The same circle run in the opposite direction (CSV `x,y`): adds H.
    #[arg(long)]
    pub reverse: Option<PathBuf>,
    /// Predict the test of this stored machine by the service's simulation (needs --server).
    #[arg(long, requires = "server", conflicts_with = "file")]
    pub simulate: Option<String>,
    /// Feed of the simulated test, mm/min.
    #[arg(long, requires = "simulate")]
    pub feed: Option<f64>,
    /// Evaluate on this running service instead of locally.
    #[arg(long, env = "TRUECUT_SERVER")]
    pub server: Option<String>,
    /// Bearer token for --server.
    #[arg(long, env = "TRUECUT_TOKEN", hide_env_values = true)]
    pub token: Option<String>,
    /// Print the answer JSON instead of the figures.
    #[arg(long)]
    pub json: bool,
}

fn parse_pair(s: &str) -> Result<[f64; 2], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|p| p.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| format!("'{s}': {e}; write x,y in mm"))?;
    match v.as_slice() {
        [x, y] if x.is_finite() && y.is_finite() => Ok([*x, *y]),
        _ => Err(format!("'{s}' must be two finite numbers x,y (mm)")),
    }
}

/// CSV rows as (1-based line number, fields).
type CsvRows = Vec<(usize, Vec<String>)>;

/// A CSV as column names (lower case, unit suffixes removed) and rows of fields.
fn read_csv(path: &Path) -> anyhow::Result<(Vec<String>, CsvRows)> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty() && !l.trim_start().starts_with('#'));
    let (_, header) = lines
        .next()
        .with_context(|| format!("{} is empty; it needs a header row", path.display()))?;
    let sep = [';', '\t', ',']
        .into_iter()
        .find(|c| header.contains(*c))
        .unwrap_or(',');
    let names = header
        .split(sep)
        .map(|n| {
            let n = n.trim().trim_matches('"').to_ascii_lowercase();
            ["[mm]", "(mm)", "_mm", "[s]", "(s)", "_s"]
                .iter()
                .fold(n, |n, s| {
                    n.strip_suffix(s)
                        .map_or(n.clone(), |t| t.trim().to_string())
                })
        })
        .collect();
    let rows = lines
        .map(|(i, l)| (i + 1, l.split(sep).map(|f| f.trim().to_string()).collect()))
        .collect();
    Ok((names, rows))
}

fn column(names: &[String], want: &str, path: &Path) -> anyhow::Result<usize> {
    names.iter().position(|n| n == want).with_context(|| {
        format!(
            "{}: no '{want}' column (columns: {})",
            path.display(),
            names.join(",")
        )
    })
}

fn number(rows: &[(usize, Vec<String>)], col: usize, path: &Path) -> anyhow::Result<Vec<f64>> {
    rows.iter()
        .map(|(line, f)| {
            let raw = f.get(col).map(String::as_str).unwrap_or("");
            raw.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .with_context(|| {
                    format!(
                        "{} line {line}: '{raw}' is not a finite number",
                        path.display()
                    )
                })
        })
        .collect()
}

/// The ISO 230-2 request a file holds (see [`Args2`]).
pub fn read_230_2(path: &Path, period_s: Option<f64>) -> anyhow::Result<Iso2302Request> {
    if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"))
    {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read {}", path.display()))?;
        return serde_json::from_str(&text)
            .with_context(|| format!("{} is not an ISO 230-2 body", path.display()));
    }
    let (names, rows) = read_csv(path)?;
    if names.iter().any(|n| n == "commanded") {
        let commanded = number(&rows, column(&names, "commanded", path)?, path)?;
        let measured = number(&rows, column(&names, "measured", path)?, path)?;
        let period_s = match (period_s, names.iter().position(|n| n == "t")) {
            (Some(p), _) => p,
            (None, Some(c)) => {
                let t = number(&rows, c, path)?;
                if t.len() < 2 {
                    bail!("{}: too few rows to read the period from t", path.display());
                }
                (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64
            }
            (None, None) => bail!(
                "{}: a logged run needs a t column or --period-s",
                path.display()
            ),
        };
        return Ok(Iso2302Request {
            trace: Some(TraceBody {
                period_s,
                commanded,
                measured,
                ..TraceBody::default()
            }),
            ..Iso2302Request::default()
        });
    }
    let target = number(&rows, column(&names, "target", path)?, path)?;
    let measured = number(&rows, column(&names, "measured", path)?, path)?;
    let dcol = column(&names, "direction", path)?;
    let mut req = Iso2302Request {
        targets: Some(Vec::new()),
        forward: Some(Vec::new()),
        backward: Some(Vec::new()),
        ..Iso2302Request::default()
    };
    let (targets, fwd, bwd) = match (&mut req.targets, &mut req.forward, &mut req.backward) {
        (Some(t), Some(f), Some(b)) => (t, f, b),
        _ => unreachable!("all three were just set"),
    };
    for (k, (line, fields)) in rows.iter().enumerate() {
        let dir = fields
            .get(dcol)
            .map(|d| d.to_ascii_lowercase())
            .unwrap_or_default();
        let forward = match dir.as_str() {
            "fwd" | "forward" | "+" | "up" | "positive" | "pos" => true,
            "bwd" | "backward" | "-" | "down" | "negative" | "neg" => false,
            other => bail!(
                "{} line {line}: direction '{other}' is not fwd/+ or bwd/-",
                path.display()
            ),
        };
        let i = match targets.iter().position(|t| *t == target[k]) {
            Some(i) => i,
            None => {
                targets.push(target[k]);
                fwd.push(Vec::new());
                bwd.push(Vec::new());
                targets.len() - 1
            }
        };
        if forward { &mut fwd[i] } else { &mut bwd[i] }.push(measured[k]);
    }
    Ok(req)
}

fn server_args(server: &str, token: &Option<String>) -> ServerArgs {
    ServerArgs {
        server: server.to_string(),
        token: token.clone(),
        timeout_s: 300,
    }
}

/// POSTs `body` as JSON to `path` and returns the answer's JSON (a refusal is the client's
/// error, with its exit code).
fn post_json(
    client: &Client,
    path: &str,
    body: &impl serde::Serialize,
) -> anyhow::Result<serde_json::Value> {
    let rb = client.request(Method::POST, path).json(body);
    client
        .runtime
        .block_on(async { anyhow::Ok(client.send(rb).await?.json().await?) })
}

/// Runs `truecut iso230-2`.
pub fn run_2(args: Args2) -> anyhow::Result<()> {
    let mut req = read_230_2(&args.file, args.period_s)?;
    match &mut req.trace {
        Some(t) => {
            t.settle_speed_mm_s = args.settle_speed_mm_s.or(t.settle_speed_mm_s);
            t.min_settled_s = args.min_settled_s.or(t.min_settled_s);
        }
        None if args.settle_speed_mm_s.is_some() || args.min_settled_s.is_some() => bail!(
            "--settle-speed-mm-s and --min-settled-s read a logged run (CSV commanded,measured); \
             {} is a table",
            args.file.display()
        ),
        None => {}
    }
    let answer: serde_json::Value = match &args.server {
        None => {
            let answer = match &req.trace {
                Some(t) => {
                    let trace = PositioningTrace {
                        period_s: t.period_s,
                        commanded_mm: t.commanded.clone(),
                        measured_mm: t.measured.clone(),
                    };
                    let d = TraceOptions::default();
                    let opts = TraceOptions {
                        min_dwell_s: t.min_dwell_s.unwrap_or(d.min_dwell_s),
                        target_tolerance_mm: t.target_tolerance_mm.unwrap_or(d.target_tolerance_mm),
                        settle_speed_mm_s: t.settle_speed_mm_s.unwrap_or(d.settle_speed_mm_s),
                        min_settled_s: t.min_settled_s.unwrap_or(d.min_settled_s),
                    };
                    Iso2302Answer::from_trace(&evaluate_trace(&trace, &opts)?, t.period_s)
                }
                None => Iso2302Answer::from_axis(&evaluate_table(&PositionTable {
                    targets_mm: req.targets.clone().unwrap_or_default(),
                    forward_mm: req.forward.clone().unwrap_or_default(),
                    backward_mm: req.backward.clone().unwrap_or_default(),
                })?),
            };
            serde_json::to_value(answer)?
        }
        Some(server) => {
            let client = Client::new(&server_args(server, &args.token))?;
            let path = match (&args.machine, &args.axis) {
                (Some(m), Some(a)) => {
                    req.label = args.label.clone();
                    format!("/v1/machines/{m}/axes/{a}/iso230-2")
                }
                _ => "/v1/iso230-2".to_string(),
            };
            post_json(&client, &path, &req)?
        }
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&answer)?);
        return Ok(());
    }
    let a: Iso2302Answer = serde_json::from_value(answer.clone())
        .context("the server's answer is not an ISO 230-2 answer")?;
    if let Some(id) = answer.get("id").and_then(|v| v.as_str()) {
        eprintln!("stored run {id}");
    }
    print!("{}", format_230_2(&a));
    Ok(())
}

/// The figures and table of an ISO 230-2 answer as text, in µm.
pub fn format_230_2(a: &Iso2302Answer) -> String {
    let um = |v: f64| format!("{:8.2}", v * 1e3);
    let mut s = format!("{} ({} targets), µm\n", a.standard, a.targets.len());
    s += &format!(
        "A {}   A_fwd {}   A_bwd {}\n",
        um(a.A),
        um(a.A_fwd),
        um(a.A_bwd)
    );
    s += &format!(
        "E {}   E_fwd {}   E_bwd {}\n",
        um(a.E),
        um(a.E_fwd),
        um(a.E_bwd)
    );
    s += &format!(
        "R {}   R_fwd {}   R_bwd {}\n",
        um(a.R),
        um(a.R_fwd),
        um(a.R_bwd)
    );
    s += &format!(
        "M {}   B     {}   B_avg {}\n",
        um(a.M),
        um(a.B),
        um(a.B_avg)
    );
    s += "  target_mm  mean_fwd  mean_bwd     s_fwd     s_bwd         B         R\n";
    for t in &a.targets {
        s += &format!(
            "{:11.4} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9}\n",
            t.target,
            um(t.mean_fwd),
            um(t.mean_bwd),
            um(t.s_fwd),
            um(t.s_bwd),
            um(t.B),
            um(t.R)
        );
    }
    if let Some(used) = &a.used {
        s += &format!(
            "{} readings used from the logged run, {} settled stops ignored\n",
            used.len(),
            a.ignored.as_ref().map_or(0, Vec::len)
        );
    }
    if let Some(st) = &a.settling {
        s += &format!(
            "settled: slower than {} mm/s for {} s (window {:.3} s); measured offset {:.4} mm\n",
            st.settle_speed_mm_s, st.min_settled_s, st.window_s, st.measured_offset_mm
        );
    }
    for w in &a.warnings {
        s += &format!("warning: {w}\n");
    }
    s
}

fn read_points(path: &Path) -> anyhow::Result<Vec<[f64; 2]>> {
    let (names, rows) = read_csv(path)?;
    let x = number(&rows, column(&names, "x", path)?, path)?;
    let y = number(&rows, column(&names, "y", path)?, path)?;
    Ok(x.into_iter().zip(y).map(|(x, y)| [x, y]).collect())
}

/// Runs `truecut iso230-4`.
pub fn run_4(args: Args4) -> anyhow::Result<()> {
    let radius = args.radius;
    let answer: serde_json::Value = if let Some(machine) = &args.simulate {
        let Some(radius) = radius else {
            bail!("--simulate needs --radius (mm)");
        };
        let server = args.server.as_deref().unwrap_or_default();
        let client = Client::new(&server_args(server, &args.token))?;
        let mut body = serde_json::json!({"radius": radius});
        if let Some(c) = args.centre {
            body["centre"] = serde_json::json!(c);
        }
        if let Some(f) = args.feed {
            body["feed"] = serde_json::json!(f);
        }
        let answer = post_json(
            &client,
            &format!("/v1/machines/{machine}/iso230-4/simulate"),
            &body,
        )?;
        if !args.json {
            let mut s = String::from("ISO 230-4:2005, simulated, µm\n");
            for (dir, run) in answer["runs"].as_object().into_iter().flatten() {
                let um = |k: &str| run[k].as_f64().unwrap_or(f64::NAN) * 1e3;
                s += &format!(
                    "{dir:>4}: G {:8.2}  F_max {:8.2}  F_min {:8.2}\n",
                    um("G"),
                    um("F_max"),
                    um("F_min")
                );
            }
            if let Some(h) = answer["H"].as_f64() {
                s += &format!("H {:8.2}\n", h * 1e3);
            }
            print!("{s}");
            return Ok(());
        }
        answer
    } else {
        let file = args.file.as_deref().context("give the points file")?;
        let mut req: Iso2304Request = if file
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("json"))
        {
            let text = std::fs::read_to_string(file)
                .with_context(|| format!("cannot read {}", file.display()))?;
            serde_json::from_str(&text)
                .with_context(|| format!("{} is not an ISO 230-4 body", file.display()))?
        } else {
            let Some(radius) = radius else {
                bail!("give the nominal --radius (mm)");
            };
            Iso2304Request {
                points: read_points(file)?,
                radius,
                ..Iso2304Request::default()
            }
        };
        if let Some(r) = radius {
            req.radius = r;
        }
        if args.centre.is_some() {
            req.centre = args.centre;
        }
        if let Some(rev) = &args.reverse {
            req.reverse_points = Some(read_points(rev)?);
        }
        match &args.server {
            None => {
                let first = evaluate_circle(&req.points, req.radius, req.centre)?;
                let answer = match &req.reverse_points {
                    None => Iso2304Answer::new(&first, None),
                    Some(rev) => {
                        let second = evaluate_circle(rev, req.radius, req.centre)?;
                        let h = circular_hysteresis(&req.points, rev, req.centre)?;
                        Iso2304Answer::new(&first, Some((&second, &h)))
                    }
                };
                serde_json::to_value(answer)?
            }
            Some(server) => {
                let client = Client::new(&server_args(server, &args.token))?;
                post_json(&client, "/v1/iso230-4", &req)?
            }
        }
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&answer)?);
        return Ok(());
    }
    let a: Iso2304Answer =
        serde_json::from_value(answer).context("the server's answer is not an ISO 230-4 answer")?;
    let um = |v: f64| v * 1e3;
    // Rounded to the printed nm, then + 0.0 so a centre of -1e-12 mm prints 0.000000, not
    // -0.000000 (the same circle evaluated here and on the server then reads the same).
    let nm = |v: f64| (v * 1e6).round() / 1e6 + 0.0;
    let mut s = format!(
        "{} ({} points), µm\nG {:8.2}  F_max {:8.2}  F_min {:8.2}\ncentre {:.6}, {:.6} mm  radius_fit {:.6} mm\n",
        a.standard,
        a.n,
        um(a.G),
        um(a.F_max),
        um(a.F_min),
        nm(a.centre[0]),
        nm(a.centre[1]),
        a.radius_fit
    );
    if let (Some(r), Some(h)) = (&a.reverse, a.H) {
        s += &format!(
            "reverse: G {:8.2}  F_max {:8.2}  F_min {:8.2}\nH {:8.2} at {:.1}°\n",
            um(r.G),
            um(r.F_max),
            um(r.F_min),
            um(h),
            a.H_angle_deg.unwrap_or(0.0)
        );
    }
    print!("{s}");
    Ok(())
}
