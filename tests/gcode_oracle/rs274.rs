//! Running LinuxCNC's interpreter (`rs274`, Debian package `linuxcnc-uspace`) and reading
//! its canonical machining calls back as moves in mm, by source line: kind, end point, arc
//! centre, plane and turns, and the feed rate in force.
//!
//! `rs274 -g FILE` prints one call a line, e.g.
//! `   14 N10    STRAIGHT_FEED(5.0000, 5.0000, 3.0000, 0.0000, 0.0000, 0.0000)`: the N number
//! of the source block (`N.....` when the block has none), then the call, with lengths in
//! the units in force (`USE_LENGTH_UNITS`) and in the program frame (work and tool offsets
//! removed). `ARC_FEED(first_end, second_end, first_centre, second_centre, turns,
//! axis_end, a, b, c)` names its axes in the order of the plane selected (`SELECT_PLANE`):
//! XY → (x, y, z), XZ → (z, x, y), YZ → (y, z, x); `turns` is +1 for one counter-clockwise
//! turn or part of one in that plane (first towards second axis), −1 clockwise, ±n for more.
//! `SET_FEED_RATE(f)` sets the feed in the units in force per minute; under G93 rs274 prints,
//! before each feed move, the rate that makes the move take 1/F minutes (programmed length ×
//! F). An F on the line of a G20/G21 is read in the line's new unit, as Fanuc reads it
//! (`canon::DIALECT_F_WITH_UNITS`). On an error rs274 prints the message and the offending block instead of a call, then
//! resets; [`run`] answers that message.
//!
//! The N number printed is the line being read when the call was issued: under cutter
//! compensation a move is held until the next one decides its corner, so it carries that
//! later line's number.
//!
//! A tool table (`-t`, [`tool_table`]) gives each tool's diameter in inches whatever the
//! program's units: standalone, rs274 runs with LinuxCNC's default user unit, the inch
//! (checked: `D0.25` offsets a G21 program by 3.175 mm and a G20 one by 0.125 in).
//!
//! rs274 is required: [`required`] fails the test that needs it, saying how to install it,
//! unless `TRUECUT_NO_RS274=1` asks to run without the oracle (which it then says loudly).

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Mutex;

use truecut::motion::gcode::Plane;

const MM_PER_INCH: f64 = 25.4;

/// The environment variable that lets the oracle's tests pass without rs274 (loudly).
pub const OPT_OUT: &str = "TRUECUT_NO_RS274";

/// An arc the oracle printed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OracleArc {
    /// The plane selected (SELECT_PLANE).
    pub plane: Plane,
    /// Centre, mm, in the plane's (first, second) axis order.
    pub centre_mm: [f64; 2],
    /// Turns: sign is the direction (+ counter-clockwise), magnitude the turns begun.
    pub turns: i32,
}

/// One move the oracle printed: the N number of its block (None for `N.....`), the point in
/// mm (program frame) and whether it is a feed (STRAIGHT_FEED / ARC_FEED) or a traverse.
#[derive(Clone, Debug, PartialEq)]
pub struct OracleMove {
    pub n: Option<usize>,
    pub xyz_mm: [f64; 3],
    pub feed: bool,
    /// ARC_FEED (a full circle ends where it starts and still moves).
    pub arc: bool,
    /// The arc's centre, plane and turns (ARC_FEED only).
    pub arc_geometry: Option<OracleArc>,
    /// Feed rate in force, mm/min: the last SET_FEED_RATE in the units in force when it was
    /// printed.
    pub feed_mm_min: f64,
    /// mm per printed unit of the feed rate (1 or 25.4): four decimals of it.
    pub feed_unit_mm: f64,
    /// mm per printed unit (1 or 25.4): the printout has four decimals of it.
    pub unit_mm: f64,
}

/// rs274 for a test that needs it: its path; or, without it, a failure saying how to install
/// it, unless [`OPT_OUT`] is set to 1 (then None, said loudly on stdout and stderr).
pub fn required() -> Option<PathBuf> {
    if let Some(p) = find() {
        return Some(p);
    }
    if std::env::var(OPT_OUT).is_ok_and(|v| v == "1") {
        let say = format!(
            "!!! THE G-CODE ORACLE DID NOT RUN: rs274 is not installed and {OPT_OUT}=1 asked to \
             go on without it; nothing was compared with LinuxCNC !!!"
        );
        println!("{say}");
        eprintln!("{say}");
        return None;
    }
    panic!(
        "LinuxCNC's G-code interpreter rs274 is not installed: install it with `apt-get install \
         linuxcnc-uspace` (Debian/Ubuntu; .ci/run does), or set {OPT_OUT}=1 to run without the \
         oracle"
    );
}

/// A LinuxCNC tool table (`.tbl`) with tools `T1..T99` of zero length and the given
/// diameters, mm (tool number -> mm; missing numbers have diameter 0), written in inches as
/// standalone rs274 reads them (module docs).
pub fn tool_table(diameters_mm: &dyn Fn(u32) -> f64) -> String {
    (1..=99)
        .map(|t| {
            let d_in = diameters_mm(t) / MM_PER_INCH;
            format!("T{t} P{t} Z0 D{d_in:.15} ;\n")
        })
        .collect()
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
    let (text, status) = printout(rs274, file, tools)?;
    parse(&text).map_err(|e| {
        format!(
            "{e} (exit {:?}, signal {:?}, {} lines printed, last: {:?})",
            status.code(),
            std::os::unix::process::ExitStatusExt::signal(&status),
            text.lines().count(),
            text.lines().last()
        )
    })
}

/// rs274's whole printout of `file` (stdout then stderr) with the tool table `tools`, and
/// how it exited (see [`run`] for the working folder).
pub fn printout(
    rs274: &Path,
    file: &Path,
    tools: Option<&Path>,
) -> Result<(String, std::process::ExitStatus), String> {
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
    Ok((text, out.status))
}

/// The dwells of a printout: the N number of each `DWELL(seconds)` call and its seconds
/// (LinuxCNC reads G4 P in seconds).
pub fn dwells(text: &str) -> Vec<(Option<usize>, f64)> {
    text.lines()
        .filter_map(|raw| {
            let mut parts = raw.split_whitespace();
            let (_, n_field, call) = (parts.next()?, parts.next()?, parts.next()?);
            let args = call.strip_prefix("DWELL(")?;
            let n = n_field.strip_prefix('N')?.parse::<usize>().ok();
            Some((n, numbers(args.trim_end_matches(')')).first().copied()?))
        })
        .collect()
}

fn numbers(args: &str) -> Vec<f64> {
    args.split(',')
        .filter_map(|s| s.trim().parse::<f64>().ok())
        .collect()
}

/// Reads rs274's printout (see the module docs).
pub fn parse(text: &str) -> Result<Vec<OracleMove>, String> {
    let mut scale = 1.0;
    let (mut feed_mm_min, mut feed_unit_mm) = (0.0, 1.0);
    let (mut feed_raw, mut feed_n) = (0.0, None);
    let mut plane = Plane::Xy;
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
                };
                if n.is_some() && feed_n == n {
                    // DIALECT_F_WITH_UNITS (`canon`): the F of this line in its new unit.
                    feed_mm_min = feed_raw * scale;
                    feed_unit_mm = scale;
                }
            }
            "SELECT_PLANE" => {
                plane = if args.contains("XZ") {
                    Plane::Zx
                } else if args.contains("YZ") {
                    Plane::Yz
                } else {
                    Plane::Xy
                }
            }
            "SET_FEED_RATE" => {
                feed_raw = numbers(args).first().copied().unwrap_or(0.0);
                feed_n = n;
                feed_mm_min = feed_raw * scale;
                feed_unit_mm = scale;
            }
            "STRAIGHT_FEED" | "STRAIGHT_TRAVERSE" => {
                let v = numbers(args);
                out.push(OracleMove {
                    n,
                    xyz_mm: [v[0] * scale, v[1] * scale, v[2] * scale],
                    feed: name == "STRAIGHT_FEED",
                    arc: false,
                    arc_geometry: None,
                    feed_mm_min,
                    feed_unit_mm,
                    unit_mm: scale,
                });
            }
            "ARC_FEED" => {
                let v = numbers(args);
                let (first, second, axis) = (v[0], v[1], v[5]);
                let mut xyz = [0.0; 3];
                let (a0, a1, an) = plane.axes();
                xyz[a0] = first;
                xyz[a1] = second;
                xyz[an] = axis;
                out.push(OracleMove {
                    n,
                    xyz_mm: xyz.map(|c| c * scale),
                    feed: true,
                    arc: true,
                    arc_geometry: Some(OracleArc {
                        plane,
                        centre_mm: [v[2] * scale, v[3] * scale],
                        turns: v[4].round() as i32,
                    }),
                    feed_mm_min,
                    feed_unit_mm,
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
