//! HTTP end to end: the dashboard page and its embedded assets, `GET /openapi.yaml`, the
//! dashboard's auth (Basic with the token as password, the header that guards its POSTs), and
//! the demo's second machine with a volumetric map for the dashboard's ISO 230-1 view. The
//! page itself is tested in headless Chromium by `.ci/dashboard.py`.

use crate::helpers::*;
use serde_json::{Value, json};

/// The `/assets/...` paths the page's HTML refers to.
fn referenced_assets(html: &str) -> Vec<String> {
    let mut out = Vec::new();
    for attr in ["src=\"", "href=\""] {
        let mut rest = html;
        while let Some(i) = rest.find(attr) {
            rest = &rest[i + attr.len()..];
            let end = rest.find('"').unwrap();
            if rest[..end].starts_with("/assets/") {
                out.push(rest[..end].to_string());
            }
        }
    }
    out
}

#[tokio::test]
async fn the_page_and_every_asset_it_names_are_served_and_nothing_points_elsewhere() {
    let app = spawn_app().await;
    let r = app.get("/").await;
    assert_eq!(r.status(), 200);
    assert!(
        r.headers()["content-type"]
            .to_str()
            .unwrap()
            .starts_with("text/html")
    );
    let csp = r.headers()["content-security-policy"]
        .to_str()
        .unwrap()
        .to_string();
    assert!(
        csp.contains("default-src 'none'") && csp.contains("connect-src 'self'"),
        "{csp}"
    );
    let html = r.text().await.unwrap();
    let assets = referenced_assets(&html);
    assert!(assets.len() >= 7, "{assets:?}");
    assert!(assets.iter().any(|a| a == "/assets/cam.js"), "{assets:?}");
    for path in &assets {
        let r = app.get(path).await;
        assert_eq!(r.status(), 200, "{path}");
        let ct = r.headers()["content-type"].to_str().unwrap().to_string();
        let want = if path.ends_with(".css") {
            "text/css"
        } else {
            "text/javascript"
        };
        assert!(ct.starts_with(want), "{path}: {ct}");
        let body = r.text().await.unwrap();
        assert!(body.len() > 500, "{path} is nearly empty");
        // Air-gapped shop networks: no URL of another host anywhere in the page's code (the
        // SVG namespace is a name, not a fetch).
        let stripped = body.replace("http://www.w3.org/2000/svg", "");
        assert!(
            !stripped.contains("http://")
                && !stripped.contains("https://")
                && !stripped.contains("//cdn"),
            "{path} names a remote URL"
        );
    }
    assert!(!html.contains("http://") && !html.contains("https://"));
    assert_problem(app.get("/assets/missing.js").await, 404, &["app.js"]).await;
}

#[tokio::test]
async fn openapi_yaml_is_served_and_is_the_spec() {
    let app = spawn_app_with(|c| c.tokens = Some("r-tok read".into())).await;
    // Public, like /healthz.
    let r = app.get("/openapi.yaml").await;
    assert_eq!(r.status(), 200);
    assert!(
        r.headers()["content-type"]
            .to_str()
            .unwrap()
            .starts_with("application/yaml")
    );
    let text = r.text().await.unwrap();
    let file =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/openapi.yaml")).unwrap();
    assert_eq!(text, file);
    let spec: serde_yaml::Value = serde_yaml::from_str(&text).unwrap();
    assert!(spec["paths"]["/"]["get"].is_mapping());
}

#[tokio::test]
async fn with_tokens_the_page_needs_read_and_a_browser_may_log_in_with_basic() {
    let mut app = spawn_app_with(|c| c.tokens = Some("r-tok read, a-tok admin".into())).await;
    // No credentials: 401 with a Basic challenge, so a browser asks for the token.
    let r = app.get("/").await;
    let challenge = r.headers()["www-authenticate"]
        .to_str()
        .unwrap()
        .to_string();
    assert!(challenge.starts_with("Basic realm="), "{challenge}");
    assert_problem(r, 401, &["Bearer"]).await;
    assert_eq!(app.get("/assets/app.js").await.status(), 401);
    // The /v1 challenge stays Bearer: a script's fetch must not pop up a log-in box.
    assert_eq!(
        app.get("/v1/machines").await.headers()["www-authenticate"],
        "Bearer realm=\"truecut\""
    );
    let basic = |path: &str, token: &str| {
        app.client
            .get(app.url(path))
            .basic_auth("operator", Some(token))
    };
    assert_eq!(basic("/", "r-tok").send().await.unwrap().status(), 200);
    assert_eq!(
        basic("/assets/plot.js", "r-tok")
            .send()
            .await
            .unwrap()
            .status(),
        200
    );
    assert_eq!(
        basic("/v1/machines", "r-tok")
            .send()
            .await
            .unwrap()
            .status(),
        200
    );
    assert_eq!(basic("/", "wrong").send().await.unwrap().status(), 401);
    app.token = Some("r-tok".into());
    assert_eq!(app.get("/").await.status(), 200);

    // A Basic-authenticated POST must carry the dashboard's header (cross-site requests
    // cannot add it); with it, read may compute; a Bearer POST needs no such header.
    let signal: Vec<f64> = (0..256).map(|i| (i as f64 * 0.2).sin()).collect();
    let body = json!({"signal": signal});
    let post = |with_header: bool| {
        let rb = app
            .client
            .post(app.url("/v1/decompose"))
            .basic_auth("operator", Some("r-tok"))
            .json(&body);
        if with_header {
            rb.header("x-truecut-dashboard", "1")
        } else {
            rb
        }
    };
    assert_problem(
        post(false).send().await.unwrap(),
        403,
        &["x-truecut-dashboard"],
    )
    .await;
    assert_eq!(post(true).send().await.unwrap().status(), 200);
    assert_eq!(app.post_json("/v1/decompose", &body).await.status(), 200);
    // Basic credentials carry the token's role, no more.
    let r = app
        .client
        .put(app.url("/v1/machines/x"))
        .basic_auth("operator", Some("r-tok"))
        .header("x-truecut-dashboard", "1")
        .json(&machine_xyz())
        .send()
        .await
        .unwrap();
    assert_problem(r, 403, &["'write'"]).await;
}

#[tokio::test]
async fn the_demo_has_a_machine_with_a_volumetric_map_and_two_parts() {
    let app = spawn_app().await;
    assert!(
        truecut::cli::demo::load(&app.server().state().store)
            .await
            .unwrap()
    );
    let r = app
        .get("/v1/machines/demo-vmc/volumetric-map?samples=11")
        .await;
    assert_eq!(r.status(), 200);
    let map: Value = r.json().await.unwrap();
    let axes = map["components"]["axes"].as_array().unwrap();
    assert_eq!(axes.len(), 3);
    let curves: usize = axes
        .iter()
        .map(|a| a["curves"].as_array().unwrap().len())
        .sum();
    let squareness = map["components"]["squareness"].as_array().unwrap().len();
    assert_eq!(curves + squareness, 21, "the 21 ISO 230-1 parameters");
    let list: Value = app
        .get("/v1/machines/demo/surfaces/saddle/measurements")
        .await
        .json()
        .await
        .unwrap();
    let ids: Vec<&str> = list["measurements"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m["id"].as_str().unwrap())
        .collect();
    assert!(
        ids.contains(&"demo-1") && ids.contains(&"demo-2"),
        "{ids:?}"
    );
    // The CAM view leaves "volumetric" to the service on its first run and learns from the
    // answer whether the machine has a map (to add its error to the predicted tool tip).
    let program = "G21 G90 G54\nG0 X-20 Y-10 Z5\nG1 Z0 F600\nG1 X20 F3000\nG1 Y10\nM30\n";
    let offsets = json!({"G54": [400.0, 250.0, 200.0]});
    for (machine, has_map) in [("demo-vmc", true), ("demo", false)] {
        let r = app
            .post_json(
                &format!("/v1/machines/{machine}/compensated-program"),
                &json!({"gcode": program, "contour": true, "work_offsets": offsets}),
            )
            .await;
        assert_eq!(r.status(), 200, "{machine}");
        let c: Value = r.json().await.unwrap();
        assert_eq!(c["volumetric"], has_map, "{machine}: {c}");
        assert!(c["contour"]["iterations"].as_u64().unwrap() >= 1, "{c}");
        assert_eq!(c["max_shift_mm"].as_f64().unwrap() > 0.0, has_map, "{c}");
    }
    // Loaded once: a second call finds the demo there.
    assert!(
        !truecut::cli::demo::load(&app.server().state().store)
            .await
            .unwrap()
    );
}
