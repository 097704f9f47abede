//! The real posts of `tests/data/programs` (Fanuc, Haas, Sinumerik ISO, a G41 pocket) read by
//! both interpreters and compared move by move (`crate::canon`): rapids, feeds, arcs with
//! their centres and turns, feed rates. Each line is numbered `N<line>` (`valid::numbered`)
//! so that rs274 names it; the tools have the diameters their comments give
//! ([`POST_DIAMETERS_MM`]), in rs274's tool table and in truecut's `tool_diameters`, so that
//! the G41 pocket is compared on its tool-centre path.

use std::path::Path;

use crate::canon::{Counts, Match};
use crate::{compare_moves, counts_line, oracle, oracle_options, rs274};

/// Tool diameters of the posts, mm, from their comments: T1 (pocket_finish: "T1 D6 FLAT END
/// MILL"; the other T1 programs use no G41/G42), T3 (haas_drill: "DIA 6.8 DRILL"), T5
/// (siemens_iso_turnmill: "BALL D8").
pub const POST_DIAMETERS_MM: [(u32, f64); 3] = [(1, 6.0), (3, 6.8), (5, 8.0)];

/// rs274's tool table of [`POST_DIAMETERS_MM`] (other tools diameter 0), written to
/// `dir/name`; its path.
pub fn post_tool_table(dir: &Path, name: &str) -> std::path::PathBuf {
    let table = dir.join(name);
    let by_tool = |t: u32| {
        POST_DIAMETERS_MM
            .iter()
            .find(|(n, _)| *n == t)
            .map_or(0.0, |(_, d)| *d)
    };
    std::fs::write(&table, rs274::tool_table(&by_tool)).unwrap();
    table
}

#[test]
fn real_posts_agree_with_linuxcnc() {
    let Some(rs) = oracle() else { return };
    let folder = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/programs");
    let mut files: Vec<_> = std::fs::read_dir(&folder)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "nc"))
        .collect();
    files.sort();
    assert!(!files.is_empty(), "no programs in {}", folder.display());
    let dir = tempfile::tempdir().unwrap();
    let table = post_tool_table(dir.path(), "posts.tbl");
    let options = oracle_options(&POST_DIAMETERS_MM);
    let (mut total, mut failures) = (Counts::default(), Vec::new());
    for path in &files {
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        let text = crate::valid::numbered(&std::fs::read_to_string(path).unwrap());
        let file = dir.path().join(&name);
        std::fs::write(&file, &text).unwrap();
        let cutter = text.contains("G41") || text.contains("G42");
        let how = if cutter {
            Match::Compensated
        } else {
            Match::AsPrinted
        };
        let r = rs274::run_with_tools(&rs, &file, Some(&table))
            .map_err(|e| format!("rs274 refuses it: {e}"))
            .and_then(|moves| compare_moves(&moves, &text, &options, how));
        match r {
            Ok(c) => {
                println!("{name}: agrees with rs274: {}", counts_line(&c));
                total += c;
            }
            Err(e) => failures.push(format!("{name}: {e}")),
        }
    }
    println!(
        "real posts: {} programs, {} agree with rs274: {}",
        files.len(),
        files.len() - failures.len(),
        counts_line(&total)
    );
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
