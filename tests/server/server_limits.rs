//! What a request may cost the server, each bound tested at its edge: scene costs (lights,
//! image size, path samples, GDM size), JSON and upload bodies (413 before the body is
//! read), image headers (decompression bombs), concurrent uploads, the queue's length (a
//! scene of several objects queued whole or not at all), slow and idle clients, readiness of a store that refuses writes, HTTP validators and ranges,
//! keys on HEAD and /metrics, and JSON error bodies for every rejection.

use crate::server_harness::{TestServer, database_urls};
use mesobake_bake::mesostructure::samples::{self, SampleKind};
use mesobake_bake::mesostructure::volume_format;
use mesobake_core::limits::Limits;
use mesobake_package::grid::Dims;
use mesobake_server::config::ServerConfig;
use mesobake_server::db::{PackageRow, now_ms};
use mesobake_server::storage_reserve::free_bytes;
use serde_json::{Value, json};
use std::time::{Duration, Instant};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

fn sqlite(dir: &std::path::Path) -> String {
    format!("sqlite://{}", dir.join("db.sqlite").display())
}

/// A server on a SQLite file and a blob store in `dir`, without workers, its configuration
/// changed by `edit`.
async fn start(dir: &std::path::Path, edit: impl FnOnce(&mut ServerConfig)) -> TestServer {
    TestServer::start_with(&sqlite(dir), &dir.join("data"), 1 << 20, |c| {
        c.workers = 0;
        edit(c);
    })
    .await
}

/// Uploads `body` as the volume `v.mbvol`.
async fn upload(s: &TestServer, body: Vec<u8>) -> reqwest::Response {
    reqwest::Client::new()
        .post(s.url("/api/v1/assets?kind=volume&name=v.mbvol"))
        .body(body)
        .send()
        .await
        .unwrap()
}

/// A `kind` sample volume of `side`×`side`×`side/2` voxels, encoded.
fn volume_bytes(kind: SampleKind, side: u32) -> Vec<u8> {
    let dims = Dims::new(side, side, side / 2).unwrap();
    volume_format::encode(&samples::volume(kind, dims, &Limits::default()).unwrap())
}

fn scene() -> Value {
    json!({
        "base_mesh": { "builtin": { "plane": { "size": 2.0, "segments": 4 } } },
        "mesostructure": { "sample": "chain" },
        "resolution": [16, 16, 8],
        "directions": [4, 8],
        "shell": { "thickness": 0.1, "tiles_per_uv": [2, 2] },
        "camera": { "eye": [0, 2, 2], "target": [0, 0, 0], "fov_y_degrees": 45, "width": 32, "height": 32 },
        "lights": [{ "ambient": { "radiance": [0.2, 0.2, 0.2] } }],
        "effects": ["silhouettes"]
    })
}

async fn post_json(
    s: &TestServer,
    path: &str,
    body: &Value,
) -> (u16, Value, reqwest::header::HeaderMap) {
    let r = reqwest::Client::new()
        .post(s.url(path))
        .json(body)
        .send()
        .await
        .unwrap();
    let (status, headers) = (r.status().as_u16(), r.headers().clone());
    (status, r.json().await.unwrap_or(Value::Null), headers)
}

/// Sends `head` (and nothing more) on a fresh connection and reads what comes back within
/// `wait`: the response text, and whether the server closed the connection.
async fn raw(s: &TestServer, head: &[u8], wait: Duration) -> (String, bool) {
    let mut tcp = TcpStream::connect(s.addr).await.unwrap();
    tcp.write_all(head).await.unwrap();
    let mut got = Vec::new();
    let mut buf = [0u8; 4096];
    let deadline = Instant::now() + wait;
    let closed = loop {
        match tokio::time::timeout_at(deadline.into(), tcp.read(&mut buf)).await {
            Ok(Ok(0)) | Ok(Err(_)) => break true,
            Ok(Ok(n)) => got.extend_from_slice(&buf[..n]),
            Err(_) => break false,
        }
    };
    (String::from_utf8_lossy(&got).into_owned(), closed)
}

#[tokio::test]
async fn scenes_over_the_cost_limits_are_refused_naming_the_limit() {
    let dir = tempfile::tempdir().unwrap();
    let s = start(dir.path(), |_| {}).await;
    let with = |edit: &dyn Fn(&mut Value)| {
        let mut sc = scene();
        edit(&mut sc);
        json!({ "scene": sc })
    };
    let ambient = json!({ "ambient": { "radiance": [0.001, 0.001, 0.001] } });
    let cases = [
        (
            with(&|sc| sc["lights"] = json!(vec![ambient.clone(); 65])),
            "max_lights",
        ),
        (
            with(&|sc| sc["camera"]["width"] = json!(4096)),
            "max_image_side",
        ),
        (
            with(&|sc| {
                sc["effects"] = json!(["environment_lighting"]);
                sc["environment"] = json!({ "sky": { "clear": {
                    "sun_direction": [0, 1, 0], "sun_radiance": [1, 1, 1],
                    "sun_radius_degrees": 2.5, "zenith": [0.2, 0.4, 0.9],
                    "horizon": [0.8, 0.8, 0.9], "ground": [0.2, 0.2, 0.2]
                } } });
                sc["gi"] = json!({ "path_samples": 1000 });
            }),
            "max_path_samples",
        ),
        (
            with(&|sc| sc["base_mesh"] = json!({ "builtin": { "plane": { "segments": 4096 } } })),
            "max_base_triangles",
        ),
        (
            // 1024×1024×64 voxels of material and caster (64 bytes each) alone: 4 GiB.
            with(&|sc| sc["resolution"] = json!([1024, 1024, 64])),
            "memory limit",
        ),
    ];
    for path in ["/api/v1/jobs", "/api/v1/preview"] {
        for (body, limit) in &cases {
            let (status, answer, _) = post_json(&s, path, body).await;
            assert_eq!(status, 422, "{path} {limit}: {answer}");
            let message = answer["error"].as_str().unwrap();
            assert!(message.contains(limit), "{path}: {message}");
        }
    }
    // At the limits themselves the scene is accepted.
    let at_limits = with(&|sc| {
        sc["lights"] = json!(vec![ambient.clone(); 64]);
        sc["camera"]["width"] = json!(2048);
    });
    let (status, answer, _) = post_json(&s, "/api/v1/jobs", &at_limits).await;
    assert_eq!(status, 202, "{answer}");
    let jobs: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM jobs")
        .fetch_one(&s.state.db.pool)
        .await
        .unwrap();
    assert_eq!(jobs, 1, "refused scenes queue nothing");
}

#[tokio::test]
async fn bodies_over_their_limit_get_413_before_they_are_read() {
    let dir = tempfile::tempdir().unwrap();
    let s = start(dir.path(), |c| {
        c.max_json_bytes = 4096;
    })
    .await;
    // Headers announce more than the limit and no body follows: the answer comes at once.
    for (path, limit) in [
        ("/api/v1/jobs", 4096),
        ("/api/v1/assets?kind=volume&name=v.mbvol", 1 << 20),
    ] {
        let head = format!(
            "POST {path} HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\n\
             Content-Length: {}\r\n\r\n",
            limit + 1
        );
        let start = Instant::now();
        let (text, _) = raw(&s, head.as_bytes(), Duration::from_secs(3)).await;
        assert!(text.starts_with("HTTP/1.1 413"), "{path}: {text}");
        assert!(text.contains("{\"error\":"), "{path}: a JSON error: {text}");
        assert!(
            start.elapsed() < Duration::from_secs(2),
            "{path}: answered at once"
        );
    }
    // A whole body over the limit, as a client sends it.
    let big = json!({ "scene": scene(), "padding": "x".repeat(8192) });
    let (status, answer, _) = post_json(&s, "/api/v1/jobs", &big).await;
    assert_eq!(status, 413, "{answer}");
    // A JSON body is parsed into its type: unknown fields are refused, not stored.
    let (status, answer, _) =
        post_json(&s, "/api/v1/jobs", &json!({ "scene": scene(), "x": 1 })).await;
    assert_eq!(status, 422, "{answer}");
    assert!(
        answer["error"].as_str().unwrap().contains("unknown field"),
        "{answer}"
    );
}

/// A grayscale 16-bit PNG header claiming `side` × `side` pixels, with a token IDAT: what
/// a decompression bomb looks like before it is decoded.
fn png_header(side: u32) -> Vec<u8> {
    let chunk = |kind: &[u8], data: &[u8]| {
        let mut c = (data.len() as u32).to_be_bytes().to_vec();
        c.extend_from_slice(kind);
        c.extend_from_slice(data);
        let mut h = crc32fast::Hasher::new();
        h.update(kind);
        h.update(data);
        c.extend_from_slice(&h.finalize().to_be_bytes());
        c
    };
    let mut ihdr = side.to_be_bytes().to_vec();
    ihdr.extend_from_slice(&side.to_be_bytes());
    ihdr.extend_from_slice(&[16, 0, 0, 0, 0]); // 16 bits, grayscale
    let mut png = vec![0x89, b'P', b'N', b'G', 0x0d, 0x0a, 0x1a, 0x0a];
    png.extend(chunk(b"IHDR", &ihdr));
    png.extend(chunk(
        b"IDAT",
        &[0x78, 0x9c, 0x03, 0x00, 0x00, 0x00, 0x00, 0x01],
    ));
    png.extend(chunk(b"IEND", &[]));
    png
}

#[tokio::test]
async fn image_headers_are_checked_before_decoding_and_uploads_wait_for_a_slot() {
    let dir = tempfile::tempdir().unwrap();
    let s = start(dir.path(), |c| {
        c.max_concurrent_uploads = 1;
        c.busy_wait_ms = 300;
    })
    .await;
    let client = reqwest::Client::new();
    let start = Instant::now();
    let r = client
        .post(s.url("/api/v1/assets?kind=height_field&name=bomb.png"))
        .body(png_header(16000))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 422);
    let message = r.json::<Value>().await.unwrap()["error"].to_string();
    assert!(
        message.contains("16000×16000") && message.contains("pixels"),
        "{message}"
    );
    assert!(
        start.elapsed() < Duration::from_secs(2),
        "refused from the header"
    );

    // The only validation slot is held; the next upload waits for it, then gets 503.
    let held = s.state.uploads.clone().acquire_owned().await.unwrap();
    let volume = volume_bytes(SampleKind::Grid, 8);
    let r = upload(&s, volume.clone()).await;
    assert_eq!(r.status(), 503);
    assert_eq!(r.headers()["retry-after"], "1");
    drop(held);
    // A body cut short leaves no file; once the slot is free, the same upload goes through.
    let mut cut = TcpStream::connect(s.addr).await.unwrap();
    cut.write_all(
        b"POST /api/v1/assets?kind=volume&name=cut.mbvol HTTP/1.1\r\nHost: x\r\n\
          Content-Length: 100000\r\n\r\npartial",
    )
    .await
    .unwrap();
    tokio::time::sleep(Duration::from_millis(200)).await;
    drop(cut);
    tokio::time::sleep(Duration::from_millis(200)).await;
    let r = upload(&s, volume).await;
    assert_eq!(r.status(), 201);
    let tmp = dir.path().join("data/blobs/tmp");
    let left: Vec<_> = std::fs::read_dir(&tmp).unwrap().collect();
    assert!(left.is_empty(), "temporary upload files left: {left:?}");
}

/// Opens an upload of `len` bytes and sends its body a byte every `every` until the server
/// answers or closes (or 10 s pass); returns the answer.
async fn drip_upload(addr: std::net::SocketAddr, len: u32, every: Duration) -> String {
    let mut tcp = TcpStream::connect(addr).await.unwrap();
    let head = format!(
        "POST /api/v1/assets?kind=volume&name=slow.mbvol HTTP/1.1\r\nHost: x\r\n\
         Content-Length: {len}\r\n\r\n"
    );
    tcp.write_all(head.as_bytes()).await.unwrap();
    let mut got = Vec::new();
    let mut buf = [0u8; 4096];
    let give_up = tokio::time::sleep(Duration::from_secs(10));
    tokio::pin!(give_up);
    loop {
        tokio::select! {
            () = &mut give_up => break,
            read = tcp.read(&mut buf) => match read {
                Ok(0) | Err(_) => break,
                Ok(n) => got.extend_from_slice(&buf[..n]),
            },
            () = tokio::time::sleep(every) => {
                if tcp.write_all(b"x").await.is_err() {
                    break;
                }
            }
        }
    }
    String::from_utf8_lossy(&got).into_owned()
}

#[tokio::test]
async fn slow_upload_bodies_hold_no_slot_and_are_cut_at_the_minimum_rate() {
    // Four clients dripping a byte every 200 ms (each part within body_read_timeout_ms) once
    // held every upload slot indefinitely. Now the slot is taken once the body is there, and
    // a body behind `min_upload_bytes_per_s` after its first `body_read_timeout_ms` gets 408.
    let dir = tempfile::tempdir().unwrap();
    let s = start(dir.path(), |c| {
        c.max_concurrent_uploads = 1;
        c.busy_wait_ms = 300;
        c.body_read_timeout_ms = 1_500;
        c.min_upload_bytes_per_s = 100;
    })
    .await;
    let started = Instant::now();
    let drips: Vec<_> = (0..4)
        .map(|_| tokio::spawn(drip_upload(s.addr, 100_000, Duration::from_millis(200))))
        .collect();
    tokio::time::sleep(Duration::from_millis(300)).await;
    let r = upload(&s, volume_bytes(SampleKind::Grid, 8)).await;
    assert_eq!(r.status(), 201, "an upload beside four slow ones");
    for drip in drips {
        let answer = drip.await.unwrap();
        assert!(answer.starts_with("HTTP/1.1 408"), "{answer}");
        assert!(answer.contains("min_upload_bytes_per_s"), "{answer}");
    }
    let cut_after = started.elapsed();
    assert!(
        cut_after < Duration::from_secs(6),
        "the slow bodies were cut after {cut_after:?}"
    );

    // A body that keeps the pace but not the whole-request deadline: 408 too.
    let dir = tempfile::tempdir().unwrap();
    let s = start(dir.path(), |c| {
        c.min_upload_bytes_per_s = 0;
        c.upload_timeout_ms = 1_000;
    })
    .await;
    let answer = drip_upload(s.addr, 100_000, Duration::from_millis(100)).await;
    assert!(answer.starts_with("HTTP/1.1 408"), "{answer}");
    assert!(answer.contains("upload_timeout_ms"), "{answer}");
    let tmp = dir.path().join("data/blobs/tmp");
    let left: Vec<_> = std::fs::read_dir(&tmp).unwrap().collect();
    assert!(left.is_empty(), "temporary upload files left: {left:?}");
}

#[tokio::test]
async fn the_queue_has_a_cap_and_resubmissions_pass_it() {
    let dir = tempfile::tempdir().unwrap();
    for url in database_urls(dir.path(), "queue_cap").await {
        let data = tempfile::tempdir().unwrap();
        let s = TestServer::start_with(&url, data.path(), 1 << 20, |c| {
            c.workers = 0;
            c.max_queued_jobs = 1;
        })
        .await;
        let first = json!({ "scene": scene() });
        let (status, _, _) = post_json(&s, "/api/v1/jobs", &first).await;
        assert_eq!(status, 202);
        let second = json!({ "scene": scene(), "codec": "paper-svd", "rank": 4 });
        let (status, answer, headers) = post_json(&s, "/api/v1/jobs", &second).await;
        assert_eq!(status, 429, "{answer}");
        assert!(
            answer["error"]
                .as_str()
                .unwrap()
                .contains("max_queued_jobs")
        );
        assert_eq!(headers["retry-after"], "1");
        let (status, _, _) = post_json(&s, "/api/v1/jobs", &first).await;
        assert_eq!(status, 200, "the same job again adds nothing to the queue");
    }
}

/// A scene of several objects is queued whole or not at all: its objects' new jobs (objects
/// sharing a mesostructure share one) must all fit under `max_queued_jobs`.
#[tokio::test]
async fn a_scene_of_several_objects_is_queued_whole_or_not_at_all() {
    let dir = tempfile::tempdir().unwrap();
    let data = tempfile::tempdir().unwrap();
    let url = database_urls(dir.path(), "queue_objects").await.remove(0);
    let s = TestServer::start_with(&url, data.path(), 1 << 20, |c| {
        c.workers = 0;
        c.max_queued_jobs = 2;
    })
    .await;
    let object =
        |sample: &str, name: &str| json!({ "name": name, "mesostructure": { "sample": sample } });
    let objects = |list: Vec<Value>| {
        let mut scene = scene();
        scene
            .as_object_mut()
            .unwrap()
            .insert("objects".into(), json!(list));
        json!({ "scene": scene })
    };
    let (status, _, _) = post_json(&s, "/api/v1/jobs", &json!({ "scene": scene() })).await;
    assert_eq!(status, 202);
    // The chain's job exists; weave and grid would make three: refused, nothing queued.
    let three = objects(vec![
        object("chain", "a"),
        object("weave", "b"),
        object("grid", "c"),
    ]);
    let (status, answer, _) = post_json(&s, "/api/v1/object-jobs", &three).await;
    assert_eq!(status, 429, "{answer}");
    let error = answer["error"].as_str().unwrap();
    assert!(
        error.contains("needs 2 more") && error.contains("max_queued_jobs"),
        "{error}"
    );
    assert_eq!(s.jobs().await.len(), 1);
    // Two objects of one new mesostructure add one job: it fits.
    let shared = objects(vec![
        object("chain", "a"),
        object("weave", "b"),
        object("weave", "c"),
    ]);
    let (status, answer, _) = post_json(&s, "/api/v1/object-jobs", &shared).await;
    assert_eq!(status, 202, "{answer}");
    assert_eq!(s.jobs().await.len(), 2);
}

#[tokio::test]
async fn slow_and_idle_clients_are_cut_off() {
    let dir = tempfile::tempdir().unwrap();
    let s = start(dir.path(), |c| {
        c.header_read_timeout_ms = 400;
        c.body_read_timeout_ms = 400;
    })
    .await;
    // Partial headers: closed after the header timeout.
    let (_, closed) = raw(
        &s,
        b"GET /healthz HTTP/1.1\r\nHost: x\r\n",
        Duration::from_secs(3),
    )
    .await;
    assert!(closed, "a connection with partial headers stays open");
    // Nothing at all: closed too.
    let (_, closed) = raw(&s, b"", Duration::from_secs(3)).await;
    assert!(closed, "a silent connection stays open");
    // A keep-alive connection that goes idle after its answer: closed.
    let (text, closed) = raw(
        &s,
        b"GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n",
        Duration::from_secs(3),
    )
    .await;
    assert!(text.starts_with("HTTP/1.1 200"), "{text}");
    assert!(closed, "an idle keep-alive connection stays open");
    // A body that stops arriving: 408.
    let (text, _) = raw(
        &s,
        b"POST /api/v1/jobs HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\n\
          Content-Length: 1000\r\n\r\n{\"scene\":",
        Duration::from_secs(3),
    )
    .await;
    assert!(text.starts_with("HTTP/1.1 408"), "{text}");
    // A patient client with a whole request is still served.
    let r = reqwest::get(s.url("/healthz")).await.unwrap();
    assert_eq!(r.status(), 200);
}

#[tokio::test]
async fn a_blob_store_that_refuses_writes_is_not_ready() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    let s = TestServer::start_with(&sqlite(dir.path()), &data, 1 << 20, |c| c.workers = 0).await;
    let ready = || async {
        reqwest::get(s.url("/readyz"))
            .await
            .unwrap()
            .status()
            .as_u16()
    };
    assert_eq!(ready().await, 200);
    // The probe leaves nothing behind.
    let probes = std::fs::read_dir(data.join("blobs"))
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .file_name()
                .to_string_lossy()
                .starts_with(".probe")
        })
        .count();
    assert_eq!(probes, 0);
    // The store's directory replaced by a file: no write can succeed (even as root).
    std::fs::remove_dir_all(data.join("blobs")).unwrap();
    std::fs::write(data.join("blobs"), b"not a directory").unwrap();
    assert_eq!(ready().await, 503);
    let body = reqwest::get(s.url("/readyz"))
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    assert!(
        !body.contains(&*data.to_string_lossy()),
        "no server paths: {body}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_disk_short_of_its_reserve_answers_507_and_recovers_by_itself() {
    // The reserve is set 256 MiB under what is free now; a file of 768 MiB (allocated, not
    // sparse) then takes the disk below it, as a filling disk would.
    let dir = tempfile::tempdir().unwrap();
    let free = free_bytes(dir.path()).unwrap();
    let s = start(dir.path(), |c| c.min_free_bytes = free - (256 << 20)).await;
    let ready = || async {
        let r = reqwest::get(s.url("/readyz")).await.unwrap();
        (r.status().as_u16(), r.text().await.unwrap())
    };
    assert_eq!(ready().await.0, 200);
    // A job queued before the disk fills, for the worker started below.
    let job = json!({ "scene": scene() });
    let (status, queued, _) = post_json(&s, "/api/v1/jobs", &job).await;
    assert_eq!(status, 202, "{queued}");

    let filler = dir.path().join("filler");
    let file = std::fs::File::create(&filler).unwrap();
    rustix::fs::fallocate(&file, rustix::fs::FallocateFlags::empty(), 0, 768 << 20).unwrap();
    drop(file);
    let (status, body) = ready().await;
    assert_eq!(status, 503, "{body}");
    assert!(body.contains("min_free_bytes"), "{body}");
    let r = upload(&s, volume_bytes(SampleKind::Grid, 8)).await;
    assert_eq!(r.status(), 507);
    let answer = r.text().await.unwrap();
    assert!(answer.contains("min_free_bytes"), "{answer}");
    let other = json!({ "scene": scene(), "codec": "paper-svd", "rank": 4 });
    let (status, answer, _) = post_json(&s, "/api/v1/jobs", &other).await;
    assert_eq!(status, 507, "{answer}");
    // The worker claims nothing while the disk is short.
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    mesobake_server::spawn_workers(&s.state, 1, &stop);
    tokio::time::sleep(Duration::from_millis(1500)).await;
    let job_state = || async {
        let url = s.url(&format!("/api/v1/jobs/{}", queued["id"].as_str().unwrap()));
        let job: Value = reqwest::get(url).await.unwrap().json().await.unwrap();
        job["state"].as_str().unwrap().to_owned()
    };
    assert_eq!(job_state().await, "queued");

    // Space freed: everything works again, with nothing restarted.
    std::fs::remove_file(&filler).unwrap();
    assert_eq!(ready().await.0, 200);
    assert_eq!(
        upload(&s, volume_bytes(SampleKind::Grid, 8)).await.status(),
        201
    );
    let (status, answer, _) = post_json(&s, "/api/v1/jobs", &other).await;
    assert_eq!(status, 202, "{answer}");
    let waited = Instant::now();
    while job_state().await != "succeeded" {
        assert!(
            waited.elapsed() < Duration::from_secs(60),
            "{}",
            job_state().await
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
}

#[tokio::test]
async fn validators_ranges_and_keys_follow_http() {
    let dir = tempfile::tempdir().unwrap();
    let s = start(dir.path(), |c| {
        c.require_keys = true;
        c.public_packages = false;
    })
    .await;
    use mesobake_server::auth::Scope;
    let key = s
        .state
        .db
        .create_api_key(&[Scope::Read], "r")
        .await
        .unwrap();
    let bytes: Vec<u8> = (0..1000u32).map(|i| (i % 251) as u8).collect();
    let digest = s.state.blobs.put(&bytes).unwrap();
    s.state
        .db
        .insert_package(&PackageRow {
            digest: digest.clone(),
            bytes: 1000,
            manifest: json!({}),
            created_ms: now_ms(),
        })
        .await
        .unwrap();
    let client = reqwest::Client::new();
    let path = s.url(&format!("/api/v1/packages/{digest}"));
    let etag = format!("\"{digest}\"");
    let get = |headers: &[(&str, String)]| {
        let mut r = client
            .get(&path)
            .header("authorization", format!("bearer {key}"));
        for (k, v) in headers {
            r = r.header(*k, v);
        }
        r.send()
    };
    // The scheme in lower case is accepted.
    assert_eq!(get(&[]).await.unwrap().status(), 200);
    // Weak comparison for If-None-Match.
    let r = get(&[("if-none-match", format!("W/{etag}"))])
        .await
        .unwrap();
    assert_eq!(r.status(), 304);
    // An invalid range is ignored; an unsatisfiable one is 416.
    let r = get(&[("range", "bytes=9-0".into())]).await.unwrap();
    assert_eq!(r.status(), 200);
    assert_eq!(r.bytes().await.unwrap().len(), 1000);
    let r = get(&[("range", "bytes=1000-".into())]).await.unwrap();
    assert_eq!(r.status(), 416);
    assert_eq!(r.headers()["content-range"], "bytes */1000");
    // If-Range: the range only while the validator still matches.
    let r = get(&[("range", "bytes=0-9".into()), ("if-range", etag.clone())])
        .await
        .unwrap();
    assert_eq!(r.status(), 206);
    assert_eq!(r.bytes().await.unwrap().as_ref(), &bytes[..10]);
    let r = get(&[
        ("range", "bytes=0-9".into()),
        ("if-range", "\"other\"".into()),
    ])
    .await
    .unwrap();
    assert_eq!(r.status(), 200);
    assert_eq!(r.bytes().await.unwrap().len(), 1000);
    // HEAD needs what GET needs; /metrics needs the read scope.
    assert_eq!(client.head(&path).send().await.unwrap().status(), 401);
    let r = client.head(&path).bearer_auth(&key).send().await.unwrap();
    assert_eq!(r.status(), 200);
    assert_eq!(r.headers()["content-length"], "1000");
    assert_eq!(
        client.get(s.url("/metrics")).send().await.unwrap().status(),
        401
    );
    let r = client
        .get(s.url("/metrics"))
        .bearer_auth(&key)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    let text = r.text().await.unwrap();
    assert!(
        text.contains("mesobake_requests_total{status=\"304\"} 1"),
        "{text}"
    );
    assert!(text.contains("mesobake_packages_served_total"), "{text}");
}

#[tokio::test]
async fn every_error_body_is_json() {
    let dir = tempfile::tempdir().unwrap();
    let s = start(dir.path(), |_| {}).await;
    let client = reqwest::Client::new();
    let cases = [
        (client.post(s.url("/api/v1/assets?kind=bogus&name=x")), 400),
        (client.post(s.url("/api/v1/assets")), 400),
        (client.get(s.url("/api/v1/nowhere")), 404),
        (client.get(s.url("/nowhere")), 404),
        (client.delete(s.url("/api/v1/jobs")), 405),
        (client.post(s.url("/api/v1/jobs")).body("{}"), 415),
        (
            client
                .post(s.url("/api/v1/jobs"))
                .header("content-type", "application/json")
                .body("{"),
            400,
        ),
    ];
    for (request, status) in cases {
        let r = request.send().await.unwrap();
        let url = r.url().clone();
        assert_eq!(r.status(), status, "{url}");
        assert!(
            r.headers()["content-type"]
                .to_str()
                .unwrap()
                .starts_with("application/json"),
            "{url}"
        );
        let body: Value = r.json().await.unwrap();
        assert!(
            body["error"].as_str().is_some_and(|e| !e.is_empty()),
            "{url}: {body}"
        );
    }
}

#[tokio::test]
async fn the_preview_cache_evicts_the_least_recently_used_beyond_its_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let s = start(dir.path(), |c| {
        c.preview_cache_bytes = 250;
    })
    .await;
    use mesobake_server::preview_cache::{lookup, store};
    let image = |n: u8| vec![n; 100];
    let pause = || tokio::time::sleep(Duration::from_millis(5));
    store(&s.state, "a", image(1)).await.unwrap();
    pause().await;
    store(&s.state, "b", image(2)).await.unwrap();
    pause().await;
    assert_eq!(
        lookup(&s.state, "a").await.unwrap(),
        Some(image(1)),
        "a is used again"
    );
    pause().await;
    store(&s.state, "c", image(3)).await.unwrap();
    // 300 bytes over a budget of 250: b, the least recently used, goes, blob and all.
    assert_eq!(lookup(&s.state, "b").await.unwrap(), None);
    assert!(
        s.state
            .blobs
            .get(&mesobake_server::blobs::key_of(&image(2)))
            .unwrap()
            .is_none()
    );
    assert_eq!(lookup(&s.state, "a").await.unwrap(), Some(image(1)));
    assert_eq!(lookup(&s.state, "c").await.unwrap(), Some(image(3)));
    // A cached image whose bytes are also an uploaded asset keeps its blob when evicted.
    let volume = volume_bytes(SampleKind::Grid, 8);
    let r = upload(&s, volume.clone()).await;
    assert_eq!(r.status(), 201);
    store(&s.state, "v", volume.clone()).await.unwrap();
    assert_eq!(
        lookup(&s.state, "v").await.unwrap(),
        None,
        "over the budget alone"
    );
    let key = mesobake_server::blobs::key_of(&volume);
    assert_eq!(s.state.blobs.get(&key).unwrap(), Some(volume));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn failed_jobs_name_the_asset_not_the_servers_paths() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    let s = TestServer::start(&sqlite(dir.path()), &data, 1 << 20).await;
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    mesobake_server::spawn_workers(&s.state, 1, &stop);
    let volume = volume_bytes(SampleKind::Chain, 16);
    let r = upload(&s, volume).await;
    let digest = r.json::<Value>().await.unwrap()["id"]
        .as_str()
        .unwrap()
        .to_owned();
    let mut sc = scene();
    sc["mesostructure"] = json!({ "volume": digest });
    sc["resolution"] = json!([8, 8, 4]);
    let (status, job, _) = post_json(&s, "/api/v1/jobs", &json!({ "scene": sc })).await;
    assert_eq!(status, 202, "{job}");
    let id = job["id"].as_str().unwrap();
    let start = Instant::now();
    let failed = loop {
        let j: Value = reqwest::get(s.url(&format!("/api/v1/jobs/{id}")))
            .await
            .unwrap()
            .json()
            .await
            .unwrap();
        if j["state"] == "failed" {
            break j;
        }
        assert!(start.elapsed() < Duration::from_secs(60), "{j}");
        tokio::time::sleep(Duration::from_millis(50)).await;
    };
    let error = failed["error"].as_str().unwrap();
    assert!(
        error.contains(&digest) && error.contains("8x8x4"),
        "{error}"
    );
    assert!(!error.contains(&*data.to_string_lossy()), "{error}");
    assert!(!error.contains("/blobs/"), "{error}");
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
}
