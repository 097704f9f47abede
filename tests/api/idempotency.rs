//! Uploads of one id that race, and the `Idempotency-Key` header (issue 41 items 3 and 7),
//! on both backends: concurrent same-id uploads never answer 5xx and store one record; a
//! retry with the same key and body gets the first answer (`Idempotent-Replayed: true`),
//! another body 422, a request while the first is in flight 409, a bad key 400.

use std::collections::BTreeMap;
use std::time::Duration;

use serde_json::{Value, json};

use crate::helpers::{TestApp, assert_problem, seed_machine_and_surface};

const UPLOADS: &str = "/v1/machines/m/surfaces/s/measurements";

/// Deviations of a 4 x 3 surface; `variant` changes them.
fn devs(variant: usize) -> Vec<f64> {
    (0..12)
        .map(|k| ((k * 7 + variant * 13) % 11) as f64 * 1e-3 - 0.004)
        .collect()
}

/// 40 rounds of 4 concurrent POSTs of one new id each: round r sends the same body 4 times
/// when r is even, 4 different bodies when odd. No 5xx; exactly one record per id; the other
/// answers are replays of the first (same body) or 409 naming the id (another body).
async fn same_id_uploads_race(app: TestApp) {
    seed_machine_and_surface(&app, "m", "s", 4, 3).await;
    let mut tally: BTreeMap<String, usize> = BTreeMap::new();
    for round in 0..40 {
        let id = format!("race-{round}");
        let same = round % 2 == 0;
        let sends = (0..4).map(|i| {
            let body =
                json!({"id": id, "deviations": devs(if same { round } else { round * 4 + i })});
            let req = app.client.post(app.url(UPLOADS)).json(&body);
            async move {
                let r = req.send().await.expect("request failed");
                let status = r.status().as_u16();
                let replayed = r.headers().contains_key("idempotent-replayed");
                let location = r
                    .headers()
                    .get("location")
                    .map(|v| v.to_str().unwrap().to_string());
                let text = r.text().await.unwrap();
                (status, replayed, location, text)
            }
        });
        let answers = futures::future::join_all(sends).await;
        let created: Vec<_> = answers.iter().filter(|a| a.0 == 201 && !a.1).collect();
        assert_eq!(created.len(), 1, "round {round}: {answers:?}");
        for (status, replayed, location, text) in &answers {
            *tally
                .entry(format!(
                    "{status}{}",
                    if *replayed { " replay" } else { "" }
                ))
                .or_default() += 1;
            assert!(*status < 500, "round {round}: {status} {text}");
            match (status, same) {
                (201, true) => {
                    // A replay is the first answer: same body, same Location.
                    assert_eq!(text, &created[0].3, "round {round}");
                    assert_eq!(location, &created[0].2, "round {round}");
                }
                (201, false) => assert!(!replayed, "round {round}: {text}"),
                (409, false) => {
                    assert!(text.contains(&format!("'{id}'")), "{text}");
                    assert!(text.contains("other data"), "{text}");
                }
                _ => panic!("round {round}: unexpected {status} {text} (same body: {same})"),
            }
        }
        // One record, holding the body of the upload that created it.
        let stored: Value = app
            .get(&format!("{UPLOADS}/{id}"))
            .await
            .json()
            .await
            .unwrap();
        let first: Value = serde_json::from_str(&created[0].3).unwrap();
        assert_eq!(stored["max_abs"], first["max_abs"], "round {round}");
    }
    let list: Value = app.get(UPLOADS).await.json().await.unwrap();
    assert_eq!(list["measurements"].as_array().unwrap().len(), 40);
    eprintln!("40 x 4 same-id uploads: {tally:?}");
}
on_both_backends!(same_id_uploads_race);

/// A same-id upload after the first has answered: the same data is a replay (201, same
/// body), other data 409.
async fn same_id_upload_later(app: TestApp) {
    seed_machine_and_surface(&app, "m", "s", 4, 3).await;
    let body = json!({"id": "p1", "deviations": devs(1)});
    let first = app.post_json(UPLOADS, &body).await;
    assert_eq!(first.status(), 201);
    assert!(!first.headers().contains_key("idempotent-replayed"));
    let first: Value = first.json().await.unwrap();
    let again = app.post_json(UPLOADS, &body).await;
    assert_eq!(again.status(), 201);
    assert_eq!(again.headers()["idempotent-replayed"], "true");
    assert_eq!(again.json::<Value>().await.unwrap(), first);
    assert_problem(
        app.post_json(UPLOADS, &json!({"id": "p1", "deviations": devs(2)}))
            .await,
        409,
        &["'p1'", "already exists", "other data"],
    )
    .await;
}
on_both_backends!(same_id_upload_later);

/// POST `path` with an Idempotency-Key and a JSON body (and `Prefer: respond-async` when
/// `job`): (status, replayed, location, body).
async fn keyed(
    app: &TestApp,
    path: &str,
    key: &str,
    body: &Value,
    job: bool,
) -> (u16, bool, Option<String>, String) {
    let mut req = app
        .client
        .post(app.url(path))
        .header("idempotency-key", key)
        .json(body);
    if job {
        req = req.header("prefer", "respond-async");
    }
    let r = req.send().await.expect("request failed");
    let status = r.status().as_u16();
    let replayed = match r.headers().get("idempotent-replayed") {
        Some(v) => {
            assert_eq!(v, "true");
            true
        }
        None => false,
    };
    let location = r
        .headers()
        .get("location")
        .map(|v| v.to_str().unwrap().to_string());
    (status, replayed, location, r.text().await.unwrap())
}

/// An upload without an id, retried with its key: the same id, one record; another body
/// with the key: 422; the key on another route is another key.
async fn keyed_upload_replays(app: TestApp) {
    seed_machine_and_surface(&app, "m", "s", 4, 3).await;
    let body = json!({"deviations": devs(3)});
    let first = keyed(&app, UPLOADS, "upload-1", &body, false).await;
    assert_eq!(first.0, 201, "{}", first.3);
    assert!(!first.1);
    let id = serde_json::from_str::<Value>(&first.3).unwrap()["id"]
        .as_str()
        .unwrap()
        .to_string();
    for _ in 0..3 {
        let again = keyed(&app, UPLOADS, "upload-1", &body, false).await;
        assert_eq!(
            (again.0, again.1, &again.2, &again.3),
            (201, true, &first.2, &first.3)
        );
    }
    // Quoted (a structured-field string) it is the same key.
    let quoted = keyed(&app, UPLOADS, "\"upload-1\"", &body, false).await;
    assert_eq!((quoted.0, quoted.1, &quoted.3), (201, true, &first.3));
    let list: Value = app.get(UPLOADS).await.json().await.unwrap();
    let ids: Vec<&str> = list["measurements"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m["id"].as_str().unwrap())
        .collect();
    assert_eq!(ids, [id.as_str()]);
    // The key with another body: 422, nothing stored.
    let other = keyed(
        &app,
        UPLOADS,
        "upload-1",
        &json!({"deviations": devs(4)}),
        false,
    )
    .await;
    assert_eq!(other.0, 422, "{}", other.3);
    assert!(
        other.3.contains("upload-1") && other.3.contains("another"),
        "{}",
        other.3
    );
    assert!(other.3.contains("problem") || other.3.contains("detail"));
    // The same key on another surface's uploads is another key.
    let r = app
        .put_json(
            "/v1/machines/m/surfaces/s2",
            &crate::helpers::flat_surface(4, 3),
        )
        .await;
    assert!(r.status().is_success());
    let elsewhere = keyed(
        &app,
        "/v1/machines/m/surfaces/s2/measurements",
        "upload-1",
        &body,
        false,
    )
    .await;
    assert_eq!((elsewhere.0, elsewhere.1), (201, false), "{}", elsewhere.3);
    // A refused request lets go of its key: fixed, the retry runs.
    let bad = keyed(
        &app,
        UPLOADS,
        "upload-2",
        &json!({"deviations": [0.0]}),
        false,
    )
    .await;
    assert_eq!(bad.0, 400, "{}", bad.3);
    let good = keyed(
        &app,
        UPLOADS,
        "upload-2",
        &json!({"deviations": devs(5)}),
        false,
    )
    .await;
    assert_eq!((good.0, good.1), (201, false), "{}", good.3);
    // Bad keys: 400 with a sentence.
    let long = "k".repeat(256);
    for key in ["", "two words", long.as_str()] {
        let r = app
            .client
            .post(app.url(UPLOADS))
            .header("idempotency-key", key)
            .json(&body)
            .send()
            .await
            .unwrap();
        assert_problem(r, 400, &["Idempotency-Key", "1 to 255"]).await;
    }
    let list: Value = app.get(UPLOADS).await.json().await.unwrap();
    assert_eq!(list["measurements"].as_array().unwrap().len(), 2, "{list}");
}
on_both_backends!(keyed_upload_replays);

/// A job submission retried with its key: the same job id, one job.
async fn keyed_job_replays(app: TestApp) {
    let signal: Vec<f64> = (0..300).map(|i| (i as f64 * 0.1).sin() * 1e-3).collect();
    let body = json!({"signal": signal});
    let first = keyed(&app, "/v1/decompose", "job-1", &body, true).await;
    assert_eq!(first.0, 202, "{}", first.3);
    let job = serde_json::from_str::<Value>(&first.3).unwrap()["job"]
        .as_str()
        .unwrap()
        .to_string();
    assert_eq!(first.2.as_deref(), Some(format!("/v1/jobs/{job}").as_str()));
    for _ in 0..3 {
        let again = keyed(&app, "/v1/decompose", "job-1", &body, true).await;
        assert_eq!(
            (again.0, again.1, &again.2, &again.3),
            (202, true, &first.2, &first.3)
        );
    }
    app.wait_job(&job).await;
    let jobs: Value = app.get("/v1/jobs").await.json().await.unwrap();
    assert_eq!(jobs["jobs"].as_array().unwrap().len(), 1, "{jobs}");
    let other = keyed(
        &app,
        "/v1/decompose",
        "job-1",
        &json!({"signal": &signal[..200]}),
        true,
    )
    .await;
    assert_eq!(other.0, 422, "{}", other.3);
    // A direct (200) answer is not kept: the key is free again afterwards.
    let direct = keyed(&app, "/v1/decompose", "job-2", &body, false).await;
    assert_eq!((direct.0, direct.1), (200, false), "{}", direct.3);
    let job2 = keyed(&app, "/v1/decompose", "job-2", &body, true).await;
    assert_eq!((job2.0, job2.1), (202, false), "{}", job2.3);
}
on_both_backends!(keyed_job_replays);

/// Requests with one key that race: one creates, the others are replays of it or 409 (the
/// first is still in flight); never two records, never 5xx.
async fn keyed_uploads_race(app: TestApp) {
    seed_machine_and_surface(&app, "m", "s", 4, 3).await;
    let mut tally: BTreeMap<(u16, bool), usize> = BTreeMap::new();
    for round in 0..20 {
        let key = format!("race-key-{round}");
        let body = json!({"deviations": devs(round)});
        let sends = (0..4).map(|_| keyed(&app, UPLOADS, &key, &body, false));
        let answers = futures::future::join_all(sends).await;
        let created: Vec<_> = answers.iter().filter(|a| a.0 == 201 && !a.1).collect();
        assert_eq!(created.len(), 1, "round {round}: {answers:?}");
        for a in &answers {
            *tally.entry((a.0, a.1)).or_default() += 1;
            match (a.0, a.1) {
                (201, false) => {}
                (201, true) => assert_eq!(a.3, created[0].3),
                (409, false) => assert!(a.3.contains("still being answered"), "{}", a.3),
                _ => panic!("round {round}: unexpected {a:?}"),
            }
        }
    }
    let list: Value = app.get(UPLOADS).await.json().await.unwrap();
    assert_eq!(list["measurements"].as_array().unwrap().len(), 20);
    eprintln!("20 x 4 same-key uploads: {tally:?}");
}
on_both_backends!(keyed_uploads_race);

/// A second request while the first with the key is still in flight: 409. The first one's
/// body is held back so that it is in flight for sure.
async fn keyed_in_flight_is_409(app: TestApp) {
    use tokio::io::AsyncWriteExt;
    seed_machine_and_surface(&app, "m", "s", 4, 3).await;
    let body = json!({"id": "slow", "deviations": devs(6)}).to_string();
    let mut slow = crate::helpers::raw_request(
        &app.addr,
        "POST",
        UPLOADS,
        &[
            "Content-Type: application/json",
            &format!("Content-Length: {}", body.len()),
            "Idempotency-Key: slow-1",
        ],
    )
    .await;
    slow.write_all(&body.as_bytes()[..10]).await.unwrap();
    tokio::time::sleep(Duration::from_millis(300)).await;
    let second = keyed(
        &app,
        UPLOADS,
        "slow-1",
        &serde_json::from_str(&body).unwrap(),
        false,
    )
    .await;
    assert_eq!(second.0, 409, "{}", second.3);
    assert!(second.3.contains("slow-1"), "{}", second.3);
    slow.write_all(&body.as_bytes()[10..]).await.unwrap();
    let answer = crate::helpers::raw_answer(&mut slow, Duration::from_secs(10)).await;
    assert!(answer.starts_with("HTTP/1.1 201"), "{answer}");
    let third = keyed(
        &app,
        UPLOADS,
        "slow-1",
        &serde_json::from_str(&body).unwrap(),
        false,
    )
    .await;
    assert_eq!((third.0, third.1), (201, true), "{}", third.3);
}
on_both_backends!(keyed_in_flight_is_409);

/// Keys are pruned after 24 h (the store call the pruning task makes).
async fn keys_are_pruned(app: TestApp) {
    seed_machine_and_surface(&app, "m", "s", 4, 3).await;
    let body = json!({"deviations": devs(7)});
    assert_eq!(keyed(&app, UPLOADS, "old", &body, false).await.0, 201);
    let store = &app.server().state().store;
    tokio::time::sleep(Duration::from_millis(5)).await;
    assert_eq!(
        store
            .prune_idempotency_keys(truecut::store::IDEMPOTENCY_KEEP)
            .await
            .unwrap(),
        0
    );
    assert_eq!(
        store.prune_idempotency_keys(Duration::ZERO).await.unwrap(),
        1
    );
    // Pruned, the key is free again; the upload it keys still takes the key's id, so the
    // same body meets the first record (a replay by the insert), never a twin.
    let again = keyed(&app, UPLOADS, "old", &body, false).await;
    assert_eq!((again.0, again.1), (201, true), "{}", again.3);
    let list: Value = app.get(UPLOADS).await.json().await.unwrap();
    assert_eq!(list["measurements"].as_array().unwrap().len(), 1, "{list}");
}
on_both_backends!(keys_are_pruned);

/// 20 rounds of 4 concurrent PUTs of a new machine, then of a new surface on it: one 201 and
/// three 200 each, never 5xx (update-then-insert let the later inserts fail on PostgreSQL).
async fn new_ids_put_race(app: TestApp) {
    let mut tally: BTreeMap<(String, u16), usize> = BTreeMap::new();
    for round in 0..20 {
        for what in ["machine", "surface"] {
            let path = match what {
                "machine" => format!("/v1/machines/m{round}"),
                _ => format!("/v1/machines/m{round}/surfaces/s"),
            };
            let sends = (0..4).map(|i| {
                let mut body = match what {
                    "machine" => crate::helpers::machine_xyz(),
                    _ => crate::helpers::flat_surface(4, 3),
                };
                body["name"] = json!(format!("writer {i}"));
                let req = app.client.put(app.url(&path)).json(&body);
                async move {
                    let r = req.send().await.expect("request failed");
                    (r.status().as_u16(), r.text().await.unwrap())
                }
            });
            let answers = futures::future::join_all(sends).await;
            for (status, text) in &answers {
                *tally.entry((what.to_string(), *status)).or_default() += 1;
                assert!(
                    *status == 200 || *status == 201,
                    "round {round} {what}: {status} {text}"
                );
            }
            let created = answers.iter().filter(|a| a.0 == 201).count();
            assert_eq!(created, 1, "round {round} {what}: {answers:?}");
        }
    }
    eprintln!("20 x 4 PUTs of new ids: {tally:?}");
}
on_both_backends!(new_ids_put_race);

/// Keys are scoped per token: one key sent with two tokens is two keys (two records); with
/// one token a retry is a replay.
async fn keys_are_scoped_per_token(mut app: TestApp) {
    app.token = Some("a-tok".into());
    seed_machine_and_surface(&app, "m", "s", 4, 3).await;
    let body = json!({"deviations": devs(8)});
    let mut ids = Vec::new();
    for token in ["a-tok", "w-tok", "a-tok"] {
        let r = app
            .client
            .post(app.url(UPLOADS))
            .bearer_auth(token)
            .header("idempotency-key", "shared")
            .json(&body)
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 201);
        let replayed = r.headers().contains_key("idempotent-replayed");
        let id = r.json::<Value>().await.unwrap()["id"].clone();
        ids.push((token, replayed, id));
    }
    assert!(!ids[0].1 && !ids[1].1 && ids[2].1, "{ids:?}");
    assert_ne!(ids[0].2, ids[1].2);
    assert_eq!(ids[0].2, ids[2].2);
    let list: Value = app.get(UPLOADS).await.json().await.unwrap();
    assert_eq!(list["measurements"].as_array().unwrap().len(), 2, "{list}");
}
on_both_backends!(keys_are_scoped_per_token, |c| c.tokens =
    Some("a-tok admin, w-tok write".into()));

/// The first try of a keyed request committed its record and then its instance died (kill
/// -9) before keeping the answer: the key stays claimed by the dead instance. Simulated by
/// handing the kept claim back to a gone instance's name. The retry takes the key over at
/// once (not 409 for an hour) and meets what the first try stored: one measurement, one
/// job. A claim of a live instance (this one) still answers 409.
async fn a_dead_holders_key_is_taken_over_without_a_twin(app: TestApp) {
    seed_machine_and_surface(&app, "m", "s", 4, 3).await;
    let store = app.server().state().store.clone();
    let hand_back = |key: &'static str, holder: String| {
        let store = store.clone();
        async move {
            let n = sqlx::query(
                "UPDATE idempotency_keys SET claim = $1, status = NULL, fingerprint = NULL, \
                 headers = NULL, body = NULL WHERE key = $2",
            )
            .bind(holder)
            .bind(key)
            .execute(store.pool())
            .await
            .unwrap()
            .rows_affected();
            assert_eq!(n, 1);
        }
    };
    let gone = "0190a000-0000-7000-8000-000000000000/first-try".to_string();
    let live = format!("{}/first-try", store.instance());

    let body = json!({"deviations": devs(9)});
    let first = keyed(&app, UPLOADS, "dead-1", &body, false).await;
    assert_eq!(first.0, 201, "{}", first.3);
    let id = serde_json::from_str::<Value>(&first.3).unwrap()["id"].clone();
    hand_back("dead-1", live.clone()).await;
    let held = keyed(&app, UPLOADS, "dead-1", &body, false).await;
    assert_eq!(held.0, 409, "a live holder keeps its key: {}", held.3);
    hand_back("dead-1", gone.clone()).await;
    let retry = keyed(&app, UPLOADS, "dead-1", &body, false).await;
    assert_eq!(retry.0, 201, "{}", retry.3);
    assert_eq!(
        serde_json::from_str::<Value>(&retry.3).unwrap()["id"],
        id,
        "the retry meets the first try's record"
    );
    let list: Value = app.get(UPLOADS).await.json().await.unwrap();
    assert_eq!(list["measurements"].as_array().unwrap().len(), 1, "{list}");
    // The key keeps the retry's answer: a third try is a plain replay.
    let third = keyed(&app, UPLOADS, "dead-1", &body, false).await;
    assert_eq!((third.0, third.1), (201, true), "{}", third.3);

    let signal: Vec<f64> = (0..300).map(|i| (i as f64 * 0.07).sin() * 1e-3).collect();
    let body = json!({"signal": signal});
    let first = keyed(&app, "/v1/decompose", "dead-job", &body, true).await;
    assert_eq!(first.0, 202, "{}", first.3);
    hand_back("dead-job", gone).await;
    let retry = keyed(&app, "/v1/decompose", "dead-job", &body, true).await;
    assert_eq!((retry.0, &retry.3), (202, &first.3), "the same job");
    let job = serde_json::from_str::<Value>(&first.3).unwrap()["job"]
        .as_str()
        .unwrap()
        .to_string();
    app.wait_job(&job).await;
    let jobs: Value = app.get("/v1/jobs").await.json().await.unwrap();
    assert_eq!(jobs["jobs"].as_array().unwrap().len(), 1, "one job: {jobs}");

    // An ISO 230-2 run stored under a key: the retry returns the first try's run.
    let runs = "/v1/machines/m/axes/X/iso230-2";
    let body = crate::iso230::hand_body(1.0);
    let first = keyed(&app, runs, "dead-iso", &body, false).await;
    assert_eq!(first.0, 201, "{}", first.3);
    hand_back("dead-iso", gone_again()).await;
    let retry = keyed(&app, runs, "dead-iso", &body, false).await;
    assert_eq!(retry.0, 201, "{}", retry.3);
    let id_of = |text: &str| serde_json::from_str::<Value>(text).unwrap()["id"].clone();
    assert_eq!(id_of(&retry.3), id_of(&first.3), "the same run");
    assert_eq!(retry.2, first.2, "the same Location");
    let list: Value = app.get(runs).await.json().await.unwrap();
    assert_eq!(list["runs"].as_array().unwrap().len(), 1, "one run: {list}");
}
on_both_backends!(a_dead_holders_key_is_taken_over_without_a_twin);

/// A claim of an instance that no longer exists (no row in `instances`).
fn gone_again() -> String {
    "0190a000-0000-7000-8000-000000000001/first-try".to_string()
}
