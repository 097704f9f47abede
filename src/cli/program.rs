//! `truecut program --machine ID [--contour] FILE > OUT`: one command for a post-processor's
//! pipeline. Posts the program to `POST /v1/machines/{id}/compensated-program`, writes the
//! compensated program to stdout (or `--output`, replaced only on success) and the warnings
//! to stderr, follows a `202` job, and exits with the client commands' codes.

use std::collections::BTreeMap;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use reqwest::Method;
use serde_json::{Value, json};

use super::client::{Client, ServerArgs};
use super::jobs::follow;

/// Compensate a G-code program on a running service (for a post-processor's pipeline).
///
/// Volumetric pre-compensation is on when the machine has a volumetric map (unless
/// `--no-volumetric`); `--contour` adds the contour pre-distortion against the machine's servo
/// model. The compensated program goes to stdout byte for byte as the service wrote it; every
/// warning goes to stderr as `warning: FILE: ...`, then one summary line. A program that is
/// not UTF-8 is read as Latin-1 (Windows posts) and written back in Latin-1.
#[derive(Debug, clap::Args)]
#[command(after_help = "Example:\n  \
    truecut program --server http://127.0.0.1:8080 --machine m1 part.nc > part_comp.nc\n  \
    truecut program --machine m1 --contour --work-offset G54=300,150,100 --tool-length 1=150 part.nc -o part_comp.nc\n  \
    cat part.nc | truecut program --machine m1 - > part_comp.nc")]
pub struct Args {
    /// Where the service is.
    #[command(flatten)]
    pub server: ServerArgs,
    /// Machine id (as stored on the service).
    #[arg(long)]
    pub machine: String,
    /// The program the post wrote (`-` for stdin).
    pub file: PathBuf,
    /// Contour pre-distortion: rewrite the motion as G1 points the servo model follows along
    /// the original path.
    #[arg(long)]
    pub contour: bool,
    /// No volumetric pre-compensation (default: on when the machine has a volumetric map).
    #[arg(long)]
    pub no_volumetric: bool,
    /// Interpolation period of the contour model, s (service default 0.001).
    #[arg(long)]
    pub period_s: Option<f64>,
    /// With --contour: longest duration of the compensated program as a multiple of the
    /// original's, 1..2 (service default 1.15); more lets close corners slow further.
    #[arg(long)]
    pub max_duration_ratio: Option<f64>,
    /// Largest distance of the written path from the compensated path, mm (service default
    /// 0.001).
    #[arg(long)]
    pub tolerance_mm: Option<f64>,
    /// Refuse (exit 3) every word the reader would pass with a warning.
    #[arg(long)]
    pub strict: bool,
    /// A work offset in machine coordinates, mm: `G54=X,Y,Z` (repeat for G55..G59).
    #[arg(long = "work-offset", value_name = "G5x=X,Y,Z")]
    pub work_offsets: Vec<String>,
    /// A tool length for G43 H, mm: `H=LENGTH`, e.g. `1=150` (repeatable).
    #[arg(long = "tool-length", value_name = "H=MM")]
    pub tool_lengths: Vec<String>,
    /// Machine home for G28/G53, machine coordinates, mm: `X,Y,Z`.
    #[arg(long, value_name = "X,Y,Z")]
    pub home: Option<String>,
    /// Write the program to this file (replaced only when the command succeeds) instead of
    /// stdout.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Ask the service to run it as a background job (`Prefer: respond-async`) and follow the
    /// job: for long contour programs that would outlast --timeout-s.
    #[arg(long)]
    pub job: bool,
}

/// `X,Y,Z` as three finite numbers.
fn triple(what: &str, text: &str) -> anyhow::Result<[f64; 3]> {
    let v: Vec<f64> = text
        .split(',')
        .map(|s| s.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .ok()
        .filter(|v: &Vec<f64>| v.len() == 3 && v.iter().all(|x| x.is_finite()))
        .with_context(|| format!("{what} '{text}': give three numbers in mm, e.g. 300,150,100"))?;
    Ok([v[0], v[1], v[2]])
}

/// The JSON body from the flags and the program text.
fn body(args: &Args, gcode: &str) -> anyhow::Result<Value> {
    let mut b = json!({ "gcode": gcode, "contour": args.contour, "strict": args.strict });
    if args.no_volumetric {
        b["volumetric"] = json!(false);
    }
    if let Some(p) = args.period_s {
        b["period_s"] = json!(p);
    }
    if let Some(t) = args.tolerance_mm {
        b["tolerance_mm"] = json!(t);
    }
    if let Some(r) = args.max_duration_ratio {
        b["max_duration_ratio"] = json!(r);
    }
    let mut offsets = BTreeMap::new();
    for w in &args.work_offsets {
        let (code, xyz) = w.split_once('=').with_context(|| {
            format!("--work-offset '{w}': write it as G54=X,Y,Z (mm, machine coordinates)")
        })?;
        offsets.insert(
            code.trim().to_ascii_uppercase(),
            triple("--work-offset", xyz)?,
        );
    }
    if !offsets.is_empty() {
        b["work_offsets"] = json!(offsets);
    }
    let mut lengths = BTreeMap::new();
    for t in &args.tool_lengths {
        let (h, mm) = t
            .split_once('=')
            .with_context(|| format!("--tool-length '{t}': write it as H=MM, e.g. 1=150"))?;
        let mm: f64 = mm
            .trim()
            .parse()
            .ok()
            .filter(|x: &f64| x.is_finite())
            .with_context(|| format!("--tool-length '{t}': the length must be a number in mm"))?;
        lengths.insert(h.trim().to_string(), mm);
    }
    if !lengths.is_empty() {
        b["tool_lengths"] = json!(lengths);
    }
    if let Some(h) = &args.home {
        b["home"] = json!(triple("--home", h)?);
    }
    Ok(b)
}

/// The program's text and whether it was read as Latin-1 (not UTF-8).
fn read_program(file: &Path) -> anyhow::Result<(String, bool)> {
    let bytes = if file.as_os_str() == "-" {
        let mut b = Vec::new();
        std::io::stdin()
            .read_to_end(&mut b)
            .context("cannot read the program from stdin")?;
        b
    } else {
        std::fs::read(file).with_context(|| format!("cannot read {}", file.display()))?
    };
    Ok(match String::from_utf8(bytes) {
        Ok(s) => (s, false),
        Err(e) => (e.into_bytes().iter().map(|&b| b as char).collect(), true),
    })
}

/// Writes `bytes` to `path` through a temporary file beside it, so a failed run never leaves
/// a half-written program.
fn write_atomically(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(format!(".{}.tmp", std::process::id()));
    let tmp = PathBuf::from(tmp);
    let written = std::fs::write(&tmp, bytes).and_then(|()| std::fs::rename(&tmp, path));
    if written.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    written.with_context(|| format!("cannot write {}", path.display()))
}

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    let (gcode, latin1) = read_program(&args.file)?;
    let name = if args.file.as_os_str() == "-" {
        "stdin".to_string()
    } else {
        args.file.display().to_string()
    };
    if gcode.trim().is_empty() {
        bail!("{name} is empty: give the program the post wrote");
    }
    let body = body(&args, &gcode)?;
    let client = Client::new(&args.server)?;
    let path = format!("/v1/machines/{}/compensated-program", args.machine);
    let mut rb = client.request(Method::POST, &path).json(&body);
    if args.job {
        rb = rb.header("prefer", "respond-async");
    }
    let (status, answer) = client.runtime.block_on(async {
        let resp = client.send(rb).await?;
        let status = resp.status().as_u16();
        anyhow::Ok((status, resp.json::<Value>().await?))
    })?;
    let answer = match answer.get("job").and_then(Value::as_str) {
        Some(id) if status == 202 => {
            eprintln!("job {id} accepted; following it");
            follow(&client, id)?
        }
        _ => answer,
    };
    let Some(program) = answer.get("gcode").and_then(Value::as_str) else {
        bail!("the service's answer has no program (gcode): {answer}");
    };
    for w in answer["warnings"].as_array().into_iter().flatten() {
        eprintln!("warning: {name}: {}", w.as_str().unwrap_or_default());
    }
    let mut summary = format!(
        "{name} compensated on machine {}: {} blocks",
        args.machine, answer["blocks"]
    );
    if answer["volumetric"] != json!(false) {
        let shift = answer["max_shift_mm"].as_f64().unwrap_or(f64::NAN);
        summary += &format!(", largest volumetric shift {:.1} µm", shift * 1000.0);
    }
    if let Some(c) = answer.get("contour").filter(|c| c.is_object()) {
        let um = |k: &str| c[k].as_f64().unwrap_or(f64::NAN) * 1000.0;
        summary += &format!(
            "; simulated contour error RMS {:.2} -> {:.2} µm, max {:.2} -> {:.2} µm",
            um("original_rms_mm"),
            um("compensated_rms_mm"),
            um("original_max_mm"),
            um("compensated_max_mm")
        );
    }
    let bytes: Vec<u8> = if latin1 {
        program
            .chars()
            .map(|c| u8::try_from(u32::from(c)).unwrap_or(b'?'))
            .collect()
    } else {
        program.as_bytes().to_vec()
    };
    match &args.output {
        Some(out) => {
            write_atomically(out, &bytes)?;
            eprintln!("{summary}; written to {}", out.display());
        }
        None => {
            let mut stdout = std::io::stdout().lock();
            stdout
                .write_all(&bytes)
                .and_then(|()| stdout.flush())
                .context("cannot write the program to stdout")?;
            eprintln!("{summary}");
        }
    }
    Ok(())
}
