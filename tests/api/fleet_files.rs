//! The fleet file as an operator would ship it (issue 41 item 5): compose.yaml (read as YAML,
//! anchors merged), deploy/nginx.conf (its directives), the secrets and initdb scripts
//! (text). The properties: no secret with a default anyone knows, a non-superuser database
//! role, a proxy that streams bodies under the service's own limit and hands truecut's 503
//! (with Retry-After) to the client instead of retrying or counting it, its own 503 in
//! truecut's problem+json shape, a proxy that waits for healthy instances, instances that
//! get their shutdown grace, resource limits and rotated logs everywhere, and a migration
//! step before the instances.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Duration;

use serde_json::Value as Json;
use serde_yaml::Value;
use truecut::config::{Config, DEFAULT_MAX_BODY_BYTES};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn read(path: &str) -> String {
    std::fs::read_to_string(root().join(path)).unwrap_or_else(|e| panic!("{path}: {e}"))
}

/// compose.yaml with its `<<:` merges applied.
fn compose() -> Value {
    let mut doc: Value = serde_yaml::from_str(&read("compose.yaml")).unwrap();
    doc.apply_merge().unwrap();
    doc
}

fn services(doc: &Value) -> BTreeMap<String, Value> {
    doc["services"]
        .as_mapping()
        .expect("services")
        .iter()
        .map(|(k, v)| (k.as_str().unwrap().to_string(), v.clone()))
        .collect()
}

/// The services that run `truecut serve` (the image's default command).
fn instances(doc: &Value) -> BTreeMap<String, Value> {
    let image = doc["services"]["truecut1"]["image"].clone();
    assert!(image.is_string(), "truecut1 names the image it builds");
    services(doc)
        .into_iter()
        .filter(|(_, s)| s["image"] == image && s.get("command").is_none())
        .collect()
}

fn env_of(service: &Value) -> BTreeMap<String, String> {
    match service.get("environment") {
        Some(Value::Mapping(m)) => m
            .iter()
            .map(|(k, v)| {
                let v = match v {
                    Value::String(s) => s.clone(),
                    other => serde_yaml::to_string(other).unwrap().trim().to_string(),
                };
                (k.as_str().unwrap().to_string(), v)
            })
            .collect(),
        None => BTreeMap::new(),
        Some(other) => panic!("environment as a mapping, not {other:?}"),
    }
}

/// A compose duration (`40s`, `1m30s`, `2m`).
fn compose_duration(text: &str) -> Duration {
    let mut total = 0.0;
    let mut number = String::new();
    for c in text.chars() {
        if c.is_ascii_digit() || c == '.' {
            number.push(c);
            continue;
        }
        let unit = match c {
            'h' => 3600.0,
            'm' => 60.0,
            's' => 1.0,
            _ => panic!("unit {c} in {text}"),
        };
        total += number.parse::<f64>().unwrap() * unit;
        number.clear();
    }
    assert!(number.is_empty(), "{text}: a number without a unit");
    Duration::from_secs_f64(total)
}

/// nginx.conf's statements (`directive arg...`), comments dropped, each with the path of
/// blocks it is in (`server`, `location /`, `location @unavailable`, `upstream truecut`).
fn nginx() -> Vec<(String, Vec<String>)> {
    let text = read("deploy/nginx.conf");
    let mut code = String::new();
    for line in text.lines() {
        // a '#' starts a comment outside quotes (the JSON bodies hold none)
        let mut in_quote = false;
        for c in line.chars() {
            if c == '\'' {
                in_quote = !in_quote;
            }
            if c == '#' && !in_quote {
                break;
            }
            code.push(c);
        }
        code.push('\n');
    }
    let mut out = Vec::new();
    let mut blocks: Vec<String> = Vec::new();
    let mut current = String::new();
    let mut in_quote = false;
    for c in code.chars() {
        match c {
            '\'' => {
                in_quote = !in_quote;
                current.push(c);
            }
            ';' if !in_quote => {
                out.push((current.trim().to_string(), blocks.clone()));
                current.clear();
            }
            '{' if !in_quote => {
                blocks.push(current.split_whitespace().collect::<Vec<_>>().join(" "));
                current.clear();
            }
            '}' if !in_quote => {
                blocks.pop();
                current.clear();
            }
            _ => current.push(c),
        }
    }
    out
}

/// The arguments of every `name` directive (with its blocks).
fn directives(name: &str) -> Vec<(Vec<String>, Vec<String>)> {
    nginx()
        .into_iter()
        .filter_map(|(stmt, blocks)| {
            let mut words = stmt.split_whitespace();
            (words.next() == Some(name))
                .then(|| (words.map(str::to_string).collect::<Vec<_>>(), blocks))
        })
        .collect()
}

/// nginx's size syntax: bytes, or k/m/g (×1024).
fn nginx_size(text: &str) -> u64 {
    let (number, scale) = match text.chars().last().unwrap().to_ascii_lowercase() {
        'k' => (&text[..text.len() - 1], 1u64 << 10),
        'm' => (&text[..text.len() - 1], 1 << 20),
        'g' => (&text[..text.len() - 1], 1 << 30),
        _ => (text, 1),
    };
    number.parse::<u64>().unwrap() * scale
}

#[test]
fn compose_holds_no_secret_anyone_knows() {
    let text = read("compose.yaml");
    for known in [
        "change-me",
        "fleet-admin",
        "POSTGRES_PASSWORD:",
        "TRUECUT_TOKENS:",
    ] {
        assert!(!text.contains(known), "compose.yaml holds {known}");
    }
    // every ${VAR:-default} / ${VAR-default} interpolation has an empty default
    for piece in text.split("${").skip(1) {
        let inside = &piece[..piece.find('}').expect("a closed ${...}")];
        if let Some((_, default)) = inside.split_once('-') {
            assert!(default.is_empty(), "${{{inside}}} has a default");
        }
    }
    let doc = compose();
    for (name, service) in services(&doc) {
        let env = env_of(&service);
        for key in [
            "POSTGRES_PASSWORD",
            "TRUECUT_TOKENS",
            "TRUECUT_TOKEN",
            "PGPASSWORD",
        ] {
            assert!(
                !env.contains_key(key),
                "{name} sets {key} in its environment"
            );
        }
        if let Some(url) = env.get("DATABASE_URL") {
            let userinfo = url.split("://").nth(1).unwrap().split('@').next().unwrap();
            assert!(
                !userinfo.contains(':'),
                "{name}: DATABASE_URL holds a password"
            );
            assert_eq!(userinfo, "truecut", "{name} connects as the truecut role");
            assert!(
                env.contains_key("TRUECUT_DATABASE_PASSWORD_FILE"),
                "{name} reads the database password from a file"
            );
        }
    }
    for (name, instance) in instances(&doc) {
        let env = env_of(&instance);
        assert!(
            env.contains_key("TRUECUT_TOKENS_FILE"),
            "{name} reads its tokens from a file"
        );
    }
    let db_env = env_of(&doc["services"]["db"]);
    assert!(db_env.contains_key("POSTGRES_PASSWORD_FILE"), "{db_env:?}");
    assert_ne!(
        db_env.get("POSTGRES_USER").map(String::as_str),
        Some("truecut"),
        "truecut's role is not the superuser the image creates"
    );
    // the check token is there only on request: passed through from the environment of
    // `up`, with no value of its own
    assert!(
        doc["services"]["secrets"]["environment"]["TRUECUT_CHECK_TOKEN"].is_null(),
        "{:?}",
        doc["services"]["secrets"]["environment"]
    );
}

#[test]
fn secrets_are_random_and_made_once_and_the_role_is_no_superuser() {
    let doc = compose();
    let secrets = &doc["services"]["secrets"];
    assert_eq!(secrets["restart"], "no");
    let mounts = serde_yaml::to_string(&secrets["volumes"]).unwrap();
    assert!(mounts.contains("./deploy/fleet-secrets.sh:"), "{mounts}");
    let script = read("deploy/fleet-secrets.sh");
    assert!(
        script.contains("/dev/urandom"),
        "secrets come from /dev/urandom"
    );
    assert!(
        script.contains("if [ -s \"$1\" ]"),
        "a secret is made only when its file is missing or empty"
    );
    for file in [
        "postgres-password",
        "truecut-password",
        "admin-token",
        "db-password",
        "tokens",
    ] {
        assert!(script.contains(file), "fleet-secrets.sh makes {file}");
    }
    // the db service starts after it, the instances too
    assert_eq!(
        doc["services"]["db"]["depends_on"]["secrets"]["condition"],
        "service_completed_successfully"
    );
    for (name, instance) in instances(&doc) {
        assert_eq!(
            instance["depends_on"]["secrets"]["condition"], "service_completed_successfully",
            "{name}"
        );
    }
    let initdb = read("deploy/initdb/10-truecut-role.sh");
    assert!(
        initdb.contains(
            "CREATE ROLE truecut LOGIN NOSUPERUSER NOCREATEDB NOCREATEROLE NOREPLICATION"
        ),
        "{initdb}"
    );
    assert!(initdb.contains("CREATE DATABASE truecut OWNER truecut"));
    let db_mounts = serde_yaml::to_string(&doc["services"]["db"]["volumes"]).unwrap();
    assert!(
        db_mounts.contains("./deploy/initdb:/docker-entrypoint-initdb.d"),
        "{db_mounts}"
    );
}

#[test]
fn the_proxy_streams_bodies_under_the_service_s_own_limit() {
    let buffering = directives("proxy_request_buffering");
    assert!(!buffering.is_empty(), "proxy_request_buffering is set");
    for (args, blocks) in &buffering {
        assert_eq!(args, &["off"], "in {blocks:?}");
    }
    let limits = directives("client_max_body_size");
    assert!(!limits.is_empty(), "client_max_body_size is set");
    for (args, blocks) in limits {
        assert_eq!(
            nginx_size(&args[0]),
            DEFAULT_MAX_BODY_BYTES as u64,
            "client_max_body_size in {blocks:?} is truecut's --max-body-bytes default"
        );
    }
    assert_eq!(
        Config::new("127.0.0.1:0".parse().unwrap(), PathBuf::new()).max_body_bytes,
        DEFAULT_MAX_BODY_BYTES
    );
    // no instance overrides the service's limit in compose.yaml
    for (name, instance) in instances(&compose()) {
        assert!(
            !env_of(&instance).contains_key("TRUECUT_MAX_BODY_BYTES"),
            "{name} changes --max-body-bytes: change nginx's client_max_body_size with it"
        );
    }
}

#[test]
fn truecut_s_503_reaches_the_client_and_never_marks_an_instance_down() {
    let next = directives("proxy_next_upstream");
    assert!(!next.is_empty());
    for (args, blocks) in &next {
        for word in args {
            assert!(
                !word.starts_with("http_") && word != "non_idempotent",
                "proxy_next_upstream {word} in {blocks:?}: an instance's answer (503 is \
                 back-pressure) must reach the client, a POST must not be sent twice, and an \
                 http_* condition counts towards max_fails"
            );
        }
    }
    for (args, blocks) in directives("proxy_intercept_errors") {
        assert_eq!(
            args,
            ["off"],
            "truecut's errors pass unchanged ({blocks:?})"
        );
    }
    let pages = directives("error_page");
    let unavailable = pages
        .iter()
        .find(|(args, _)| args.last().map(String::as_str) == Some("@unavailable"))
        .expect("error_page ... @unavailable");
    let codes: Vec<&str> = unavailable.0[..unavailable.0.len() - 1]
        .iter()
        .map(String::as_str)
        .filter(|w| *w != "=")
        .collect();
    assert_eq!(
        codes,
        ["502", "504"],
        "only nginx's own 502/504 become its 503"
    );
    for (args, _) in &pages {
        assert!(
            !args.iter().any(|a| a == "503"),
            "truecut's 503 is never replaced: {args:?}"
        );
    }
}

/// nginx's own 503 (no instance answered) is truecut's problem+json with Retry-After.
#[tokio::test]
async fn the_proxy_s_own_503_is_truecut_s_problem_json() {
    let inside = |name: &str| -> Vec<Vec<String>> {
        nginx()
            .into_iter()
            .filter(|(_, blocks)| blocks.last().map(String::as_str) == Some(name))
            .map(|(stmt, _)| stmt.split_whitespace().map(str::to_string).collect())
            .collect()
    };
    let location = inside("location @unavailable");
    assert!(!location.is_empty(), "location @unavailable");
    let has = |words: &[&str]| {
        location
            .iter()
            .any(|s| s.len() >= words.len() && s.iter().zip(words).all(|(a, b)| a == b))
    };
    assert!(
        has(&["default_type", "application/problem+json"]),
        "{location:?}"
    );
    assert!(
        has(&["add_header", "Retry-After", "5", "always"]),
        "{location:?}"
    );
    let ret = location
        .iter()
        .find(|s| s[0] == "return")
        .expect("return 503 '...'");
    assert_eq!(ret[1], "503");
    let body = ret[2..].join(" ");
    let body: Json = serde_json::from_str(body.trim_matches('\'')).expect("a JSON body");

    // the service's own 503 body
    let theirs =
        truecut::api::error::problem_response(axum::http::StatusCode::SERVICE_UNAVAILABLE, "x");
    let bytes = axum::body::to_bytes(theirs.into_body(), 1 << 16)
        .await
        .unwrap();
    let theirs: Json = serde_json::from_slice(&bytes).unwrap();
    let keys = |v: &Json| -> Vec<String> { v.as_object().unwrap().keys().cloned().collect() };
    assert_eq!(keys(&body), keys(&theirs), "{body} vs {theirs}");
    for member in ["type", "title", "status"] {
        assert_eq!(body[member], theirs[member], "{member}: {body} vs {theirs}");
    }
    assert!(body["detail"].as_str().unwrap().contains("retry after 5 s"));
}

#[test]
fn the_proxy_waits_for_healthy_instances() {
    let doc = compose();
    let proxy = &doc["services"]["proxy"];
    let instances = instances(&doc);
    assert_eq!(instances.len(), 3, "{:?}", instances.keys());
    for (name, instance) in &instances {
        assert_eq!(
            proxy["depends_on"][name.as_str()]["condition"],
            "service_healthy",
            "the proxy waits for {name}"
        );
        assert!(instance["healthcheck"]["test"].is_sequence(), "{name}");
        assert_eq!(
            instance["depends_on"]["db"]["condition"], "service_healthy",
            "{name}"
        );
    }
    // every instance is an upstream of nginx
    let servers: Vec<String> = directives("server")
        .into_iter()
        .filter(|(_, blocks)| blocks.iter().any(|b| b.starts_with("upstream")))
        .map(|(args, _)| args[0].split(':').next().unwrap().to_string())
        .collect();
    assert_eq!(servers, instances.keys().cloned().collect::<Vec<_>>());
}

/// nginx resolves the upstream names once; an instance recreated (rolling upgrade) or
/// restarted on another address must not drop out of the fleet for good.
#[test]
fn the_proxy_follows_instances_to_new_addresses() {
    let doc = compose();
    let proxy = &doc["services"]["proxy"];
    assert_eq!(proxy["command"][1], "/fleet/proxy-start.sh", "{proxy:?}");
    let mounts = serde_yaml::to_string(&proxy["volumes"]).unwrap();
    assert!(
        mounts.contains("./deploy/proxy-start.sh:/fleet/proxy-start.sh"),
        "{mounts}"
    );
    let script = read("deploy/proxy-start.sh");
    assert!(script.contains("nginx -s reload"), "it reloads nginx");
    assert!(
        script.contains("exec nginx -g 'daemon off;'"),
        "nginx stays PID 1 (its graceful stop signal)"
    );
    // the names it watches are the upstream servers
    let default_names = script
        .lines()
        .find_map(|l| l.strip_prefix("names=${TRUECUT_UPSTREAMS:-"))
        .and_then(|l| l.strip_suffix('}'))
        .expect("names=${TRUECUT_UPSTREAMS:-...}");
    let watched: Vec<&str> = default_names.split_whitespace().collect();
    assert_eq!(
        watched,
        instances(&doc)
            .keys()
            .map(String::as_str)
            .collect::<Vec<_>>()
    );
}

#[test]
fn instances_get_their_shutdown_grace() {
    let grace = Duration::from_secs(
        Config::new("127.0.0.1:0".parse().unwrap(), PathBuf::new()).shutdown_grace_s,
    );
    for (name, instance) in instances(&compose()) {
        let configured = env_of(&instance)
            .get("TRUECUT_SHUTDOWN_GRACE_S")
            .map_or(grace, |s| Duration::from_secs(s.parse().unwrap()));
        let period = compose_duration(
            instance["stop_grace_period"]
                .as_str()
                .unwrap_or_else(|| panic!("{name} has a stop_grace_period")),
        );
        // truecut's grace, then up to a second for work that ignored its stop (cli/serve.rs)
        assert!(
            period >= configured.max(grace) + Duration::from_secs(1),
            "{name}: stop_grace_period {period:?} is shorter than truecut's grace {configured:?} + 1 s"
        );
    }
}

#[test]
fn every_service_has_limits_and_rotated_logs() {
    for (name, service) in services(&compose()) {
        let limits = &service["deploy"]["resources"]["limits"];
        assert!(
            limits["cpus"].is_string() && limits["memory"].is_string(),
            "{name}: deploy.resources.limits.cpus and .memory"
        );
        let logging = &service["logging"];
        assert_eq!(logging["driver"], "json-file", "{name}");
        assert!(
            logging["options"]["max-size"].is_string()
                && logging["options"]["max-file"].is_string(),
            "{name}: logs rotate (max-size, max-file)"
        );
    }
}

/// The migrations of a rolling upgrade are a step of their own (deploy/migrate.yaml, added to
/// the fleet with a second `-f`): the instances' image running `truecut migrate` on the
/// instances' database, after the database is healthy. It is no service of compose.yaml,
/// whose services of the built image are all instances (what a start runs and the proxy
/// serves from, as compose-check counts them).
#[test]
fn migrations_run_as_their_own_step_before_the_instances() {
    let doc = compose();
    assert!(
        doc["services"].get("migrate").is_none(),
        "migrate is no instance"
    );
    let mut step: Value = serde_yaml::from_str(&read("deploy/migrate.yaml")).unwrap();
    step.apply_merge().unwrap();
    let migrate = &step["services"]["migrate"];
    let truecut1 = &doc["services"]["truecut1"];
    assert_eq!(migrate["image"], truecut1["image"]);
    assert_eq!(migrate["command"][0], "migrate");
    assert_eq!(migrate["restart"], "no");
    assert_eq!(migrate["depends_on"]["db"]["condition"], "service_healthy");
    for dep in migrate["depends_on"].as_mapping().unwrap().keys() {
        assert!(
            doc["services"].get(dep).is_some(),
            "{dep:?} is a service of compose.yaml"
        );
    }
    let env = env_of(migrate);
    let instance_env = env_of(truecut1);
    for key in ["DATABASE_URL", "TRUECUT_DATABASE_PASSWORD_FILE"] {
        assert_eq!(env.get(key), instance_env.get(key), "{key}");
    }
    assert!(env.contains_key("TRUECUT_DB_WAIT_S"), "{env:?}");
    for volume in migrate["volumes"].as_sequence().unwrap() {
        let name = volume.as_str().unwrap().split(':').next().unwrap();
        assert!(
            doc["volumes"].get(name).is_some(),
            "volume {name} of compose.yaml"
        );
    }
    let limits = &migrate["deploy"]["resources"]["limits"];
    assert!(limits["cpus"].is_string() && limits["memory"].is_string());
    assert!(migrate["logging"]["options"]["max-size"].is_string());
    let built = truecut1["image"].clone();
    for (name, service) in services(&doc) {
        if service["image"] == built {
            assert!(
                service.get("command").is_none(),
                "{name} serves (no one-shot)"
            );
        }
    }
    for (name, instance) in instances(&doc) {
        assert!(instance["depends_on"].get("migrate").is_none(), "{name}");
        // podman-compose ignores the conditions: the instances wait for the database
        let wait: f64 = env_of(&instance)["TRUECUT_DB_WAIT_S"].parse().unwrap();
        assert!(wait >= 60.0, "{name}: TRUECUT_DB_WAIT_S {wait}");
    }
}
