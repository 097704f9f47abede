//! nginx in front of test instances, with the fleet's own proxy file (`deploy/nginx.conf`):
//! its `upstream truecut` servers are replaced by the test's instances (same parameters), its
//! `listen` by a free loopback port, and it runs as a foreground nginx with its own prefix.
//! The fault test sends its load through it, so what the clients see is what a client of
//! the compose fleet sees (the proxy's retries, its 502/504 answers, its body limit).
//!
//! Needs Debian's `nginx` binary (`apt-get install nginx`; `.ci/run` installs it). Without
//! it, [`Proxy::start`] returns `None` after saying so, unless `TRUECUT_REQUIRE_NGINX=1`
//! (CI sets it), where it panics: CI never runs the fault test without the proxy.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// A running nginx.
pub struct Proxy {
    child: Child,
    dir: tempfile::TempDir,
    /// `http://127.0.0.1:PORT`
    pub base: String,
    port: u16,
    template: String,
}

/// The nginx binary: `nginx` on PATH or Debian's /usr/sbin/nginx.
fn nginx() -> Option<PathBuf> {
    let on_path = std::env::var_os("PATH").and_then(|p| {
        std::env::split_paths(&p)
            .map(|d| d.join("nginx"))
            .find(|f| f.is_file())
    });
    on_path.or_else(|| {
        let f = PathBuf::from("/usr/sbin/nginx");
        f.is_file().then_some(f)
    })
}

/// `deploy/nginx.conf` for the test: the upstream's servers are `upstreams` (host:port), each
/// with the parameters the file gives its own, and it listens on 127.0.0.1:`port`.
pub fn site_conf(template: &str, upstreams: &[String], port: u16) -> String {
    let mut out = String::new();
    let mut in_upstream = false;
    let mut servers_written = false;
    for line in template.lines() {
        let t = line.trim_start();
        if t.starts_with("upstream truecut") {
            in_upstream = true;
        } else if in_upstream && t.starts_with('}') {
            in_upstream = false;
        }
        if in_upstream && t.starts_with("server ") {
            if !servers_written {
                // "server truecut1:8080 max_fails=… ;" → the parameters after the address.
                let params = t
                    .trim_end_matches(';')
                    .split_whitespace()
                    .skip(2)
                    .collect::<Vec<_>>()
                    .join(" ");
                for u in upstreams {
                    out.push_str(&format!("    server {u} {params};\n"));
                }
                servers_written = true;
            }
            continue;
        }
        if t.starts_with("listen ") {
            if t.contains("[::]") {
                continue;
            }
            out.push_str(&format!("    listen 127.0.0.1:{port};\n"));
            continue;
        }
        out.push_str(line);
        out.push('\n');
    }
    assert!(
        servers_written,
        "deploy/nginx.conf has no `server` line in `upstream truecut`"
    );
    out
}

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

fn running_as_root() -> bool {
    Command::new("id")
        .arg("-u")
        .output()
        .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).trim() == "0")
}

impl Proxy {
    /// nginx with the fleet's proxy file in front of `upstreams` (host:port), or `None` when
    /// nginx is not installed (and `TRUECUT_REQUIRE_NGINX` is not 1).
    pub fn start(upstreams: &[String]) -> Option<Proxy> {
        let Some(bin) = nginx() else {
            assert!(
                std::env::var("TRUECUT_REQUIRE_NGINX").as_deref() != Ok("1"),
                "TRUECUT_REQUIRE_NGINX=1 but nginx is not installed (apt-get install nginx)"
            );
            eprintln!(
                "PROXY SKIPPED: nginx is not installed (apt-get install nginx); the clients \
                 spread their requests over the instances themselves"
            );
            return None;
        };
        let template = std::fs::read_to_string(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("deploy/nginx.conf"),
        )
        .expect("deploy/nginx.conf");
        let dir = tempfile::tempdir().unwrap();
        let port = free_port();
        let d = dir.path();
        for sub in ["body", "proxy", "fastcgi", "uwsgi", "scgi", "logs"] {
            std::fs::create_dir_all(d.join(sub)).unwrap();
        }
        // Workers of a root master run as `nobody` unless told: they must write the temp dirs.
        let user = if running_as_root() {
            "user root;\n"
        } else {
            ""
        };
        let main = format!(
            "{user}worker_processes 1;\npid {p}/nginx.pid;\nerror_log {p}/logs/error.log warn;\n\
             events {{ worker_connections 1024; }}\n\
             http {{\n  access_log off;\n  client_body_temp_path {p}/body;\n  \
             proxy_temp_path {p}/proxy;\n  fastcgi_temp_path {p}/fastcgi;\n  \
             uwsgi_temp_path {p}/uwsgi;\n  scgi_temp_path {p}/scgi;\n  \
             include {p}/site.conf;\n}}\n",
            p = d.display()
        );
        std::fs::write(d.join("nginx.conf"), main).unwrap();
        std::fs::write(d.join("site.conf"), site_conf(&template, upstreams, port)).unwrap();
        let child = Command::new(bin)
            .args(["-g", "daemon off;", "-p"])
            .arg(d)
            .arg("-e")
            .arg(d.join("logs/error.log"))
            .arg("-c")
            .arg(d.join("nginx.conf"))
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("nginx starts");
        let proxy = Proxy {
            child,
            dir,
            base: format!("http://127.0.0.1:{port}"),
            port,
            template,
        };
        let t0 = Instant::now();
        while std::net::TcpStream::connect(("127.0.0.1", port)).is_err() {
            assert!(
                t0.elapsed() < Duration::from_secs(10),
                "nginx did not listen on {port}: {}",
                proxy.error_log()
            );
            std::thread::sleep(Duration::from_millis(50));
        }
        Some(proxy)
    }

    /// Points the proxy at new upstreams (an instance restarted on another port): the file is
    /// rewritten and nginx reloads it (SIGHUP; workers on the old file finish their requests).
    pub fn point_at(&mut self, upstreams: &[String]) {
        std::fs::write(
            self.dir.path().join("site.conf"),
            site_conf(&self.template, upstreams, self.port),
        )
        .unwrap();
        let status = Command::new("kill")
            .args(["-HUP", &self.child.id().to_string()])
            .status()
            .unwrap();
        assert!(status.success(), "nginx reload");
        std::thread::sleep(Duration::from_millis(300));
    }

    /// nginx's error log so far.
    pub fn error_log(&self) -> String {
        std::fs::read_to_string(self.dir.path().join("logs/error.log")).unwrap_or_default()
    }
}

impl Drop for Proxy {
    fn drop(&mut self) {
        // SIGQUIT would wait for open connections; the test is over.
        let _ = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status();
        let _ = self.child.wait();
    }
}

#[test]
fn the_fleets_proxy_file_is_pointed_at_the_test_instances() {
    let template =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("deploy/nginx.conf"))
            .unwrap();
    let conf = site_conf(
        &template,
        &["127.0.0.1:1001".into(), "127.0.0.1:1002".into()],
        4321,
    );
    assert!(conf.contains("listen 127.0.0.1:4321;"), "{conf}");
    assert!(!conf.contains("truecut1:8080"), "{conf}");
    assert_eq!(conf.matches("server 127.0.0.1:100").count(), 2, "{conf}");
    assert!(!conf.contains("listen 80"), "{conf}");
}
