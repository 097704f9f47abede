//! Running LinuxCNC's interpreter (`rs274`, Debian package `linuxcnc-uspace`) and reading
//! its canonical machining calls back as feed-move end points in mm, by source line.
//!
//! `rs274 -g FILE` prints one call a line, e.g.
//! `   14 N10    STRAIGHT_FEED(5.0000, 5.0000, 3.0000, 0.0000, 0.0000, 0.0000)`: the N number
//! of the source block (`N.....` when the block has none), then the call, with lengths in
//! the units in force (`USE_LENGTH_UNITS`) and in the program frame (work and tool offsets
//! removed). `ARC_FEED(first_end, second_end, first_centre, second_centre, turns,
//! axis_end, a, b, c)` names its axes in the order of the plane selected (`SELECT_PLANE`):
//! XY → (x, y, z), XZ → (z, x, y), YZ → (y, z, x). On an error rs274 prints the message and
//! the offending block instead of a call, then resets; [`run`] answers that message.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Mutex;

const MM_PER_INCH: f64 = 25.4;

/// One end point the oracle printed: the N number of its block (None for `N.....`), the
/// point in mm (program frame) and whether it is a feed (STRAIGHT_FEED / ARC_FEED) or a
/// traverse.
#[derive(Clone, Debug, PartialEq)]
pub struct OracleMove {
    pub n: Option<usize>,
    pub xyz_mm: [f64; 3],
    pub feed: bool,
    /// ARC_FEED (a full circle ends where it starts and still moves).
    pub arc: bool,
    /// mm per printed unit (1 or 25.4): the printout has four decimals of it.
    pub unit_mm: f64,
}

/// `rs274` when installed (PATH, /usr/bin, or LinuxCNC's own bin folder).
pub fn find() -> Option<PathBuf> {
    let mut candidates: Vec<PathBuf> = std::env::var_os("PATH")
        .map(|p| std::env::split_paths(&p).map(|d| d.join("rs274")).collect())
        .unwrap_or_default();
    candidates.push(PathBuf::from("/usr/bin/rs274"));
    candidates.push(PathBuf::from("/usr/lib/linuxcnc/bin/rs274"));
    candidates.into_iter().find(|p| p.is_file())
}

/// One rs274 at a time: two running at once die of SIGBUS now and then (about one run in
/// ten here), which looks like state they share outside their working folders.
static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

/// Runs `rs274 -g file` and reads its moves; Err(the oracle's message) when it refused the
/// program. Each run has its own working folder (rs274 keeps its parameter file,
/// `rs274ngc.var`, in the current folder).
pub fn run(rs274: &Path, file: &Path) -> Result<Vec<OracleMove>, String> {
    run_with_tools(rs274, file, None)
}

/// [`run`] with a tool table (`rs274 -t tools`; LinuxCNC's `.tbl` format), for programs that
/// change tools (`T5 M6` needs tool 5 in the table).
pub fn run_with_tools(
    rs274: &Path,
    file: &Path,
    tools: Option<&Path>,
) -> Result<Vec<OracleMove>, String> {
    let work = file.with_extension("d");
    std::fs::create_dir_all(&work).map_err(|e| format!("{}: {e}", work.display()))?;
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let mut cmd = Command::new(rs274);
    cmd.current_dir(&work);
    if let Some(t) = tools {
        cmd.arg("-t").arg(t);
    }
    let out = cmd
        .arg("-g")
        .arg(file)
        .output()
        .map_err(|e| format!("cannot run {}: {e}", rs274.display()))?;
    let text =
        String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr);
    parse(&text).map_err(|e| {
        format!(
            "{e} (exit {:?}, signal {:?}, {} lines printed, last: {:?})",
            out.status.code(),
            std::os::unix::process::ExitStatusExt::signal(&out.status),
            text.lines().count(),
            text.lines().last()
        )
    })
}

fn numbers(args: &str) -> Vec<f64> {
    args.split(',')
        .filter_map(|s| s.trim().parse::<f64>().ok())
        .collect()
}

/// Reads rs274's printout (see the module docs).
pub fn parse(text: &str) -> Result<Vec<OracleMove>, String> {
    let mut scale = 1.0;
    let mut plane = "XY";
    let mut out = Vec::new();
    let mut ended = false;
    let mut message = Vec::new();
    for raw in text.lines() {
        let line = raw.trim();
        let mut parts = line.splitn(3, char::is_whitespace);
        let (Some(seq), Some(n_field)) = (parts.next(), parts.next()) else {
            continue;
        };
        let call = parts.next().unwrap_or("").trim();
        if seq.parse::<u64>().is_err() || !n_field.starts_with('N') {
            if line != "executing" && !line.is_empty() {
                message.push(line.to_string());
            }
            continue;
        }
        let n = n_field[1..].parse::<usize>().ok();
        let (name, args) = match call.split_once('(') {
            Some((name, rest)) => (name, rest.trim_end_matches(')')),
            None => (call, ""),
        };
        match name {
            "USE_LENGTH_UNITS" => {
                scale = if args.contains("INCHES") {
                    MM_PER_INCH
                } else {
                    1.0
                }
            }
            "SELECT_PLANE" => {
                plane = if args.contains("XZ") {
                    "XZ"
                } else if args.contains("YZ") {
                    "YZ"
                } else {
                    "XY"
                }
            }
            "STRAIGHT_FEED" | "STRAIGHT_TRAVERSE" => {
                let v = numbers(args);
                out.push(OracleMove {
                    n,
                    xyz_mm: [v[0] * scale, v[1] * scale, v[2] * scale],
                    feed: name == "STRAIGHT_FEED",
                    arc: false,
                    unit_mm: scale,
                });
            }
            "ARC_FEED" => {
                let v = numbers(args);
                let (first, second, axis) = (v[0], v[1], v[5]);
                let xyz = match plane {
                    "XZ" => [second, axis, first],
                    "YZ" => [axis, first, second],
                    _ => [first, second, axis],
                };
                out.push(OracleMove {
                    n,
                    xyz_mm: xyz.map(|c| c * scale),
                    feed: true,
                    arc: true,
                    unit_mm: scale,
                });
            }
            "PROGRAM_END" => ended = true,
            _ => {}
        }
    }
    if ended {
        Ok(out)
    } else {
        Err(message.join(" | "))
    }
}
