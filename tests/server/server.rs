//! The server's API on both database backends (SQLite file; PostgreSQL on 127.0.0.1:5432
//! when present, skipped loudly otherwise): uploads with validation and deduplication,
//! package downloads with ETags and ranges, health, metrics, OpenAPI, bad requests.

use crate::server_harness::{TestServer, database_urls};
use mesobake_bake::mesostructure::samples::{self, SampleKind};
use mesobake_bake::mesostructure::volume_format;
use mesobake_core::limits::Limits;
use mesobake_package::grid::Dims;
use mesobake_server::db::{PackageRow, now_ms};

fn volume_bytes(kind: SampleKind, res: u32) -> Vec<u8> {
    let v = samples::volume(
        kind,
        Dims::new(res, res, res / 2).unwrap(),
        &Limits::default(),
    )
    .unwrap();
    volume_format::encode(&v)
}

#[tokio::test]
async fn uploads_are_validated_and_deduplicated() {
    let dir = tempfile::tempdir().unwrap();
    for url in database_urls(dir.path(), "uploads").await {
        let data = tempfile::tempdir().unwrap();
        let s = TestServer::start(&url, data.path(), 1 << 20).await;
        let client = reqwest::Client::new();
        let body = volume_bytes(SampleKind::Chain, 16);
        let upload = |body: Vec<u8>, query: &str| {
            client
                .post(s.url(&format!("/api/v1/assets?{query}")))
                .body(body)
                .send()
        };
        let r = upload(body.clone(), "kind=volume&name=chain.mbvol")
            .await
            .unwrap();
        assert_eq!(r.status(), 201, "{url}");
        let first: serde_json::Value = r.json().await.unwrap();
        assert_eq!(first["summary"]["dims"], serde_json::json!([16, 16, 8]));
        assert_eq!(first["bytes"], body.len());
        // The same bytes again: the existing asset, not a second copy.
        let r = upload(body.clone(), "kind=volume&name=again.mbvol")
            .await
            .unwrap();
        assert_eq!(r.status(), 200);
        let again: serde_json::Value = r.json().await.unwrap();
        assert_eq!(again, first);
        let id = first["id"].as_str().unwrap();
        let got: serde_json::Value = client
            .get(s.url(&format!("/api/v1/assets/{id}")))
            .send()
            .await
            .unwrap()
            .json()
            .await
            .unwrap();
        assert_eq!(got, first);
        assert_eq!(s.state.blobs.get(id).unwrap().unwrap(), body);

        // Bad requests: a status and a message naming the problem; nothing stored.
        let mut truncated = body.clone();
        truncated.truncate(body.len() / 2);
        let big = vec![0u8; 2 << 20];
        let cases: Vec<(Vec<u8>, &str, u16, &str)> = vec![
            (truncated, "kind=volume&name=t.mbvol", 422, "volume file"),
            (
                b"v 0 0 0\nf 1 2 3\n".to_vec(),
                "kind=mesh_tile&name=t.obj",
                422,
                "OBJ",
            ),
            (
                vec![0xff, 0xfe, 0x00],
                "kind=base_mesh&name=b.obj",
                422,
                "UTF-8",
            ),
            (
                body.clone(),
                "kind=volume&name=../../etc/passwd",
                422,
                "path separators",
            ),
            (
                b"not a png".to_vec(),
                "kind=height_field&name=h.png",
                422,
                "height field PNG",
            ),
            (
                body.clone(),
                "kind=height_field&name=h.png",
                409,
                "already stored as the volume asset",
            ),
            (body.clone(), "kind=teapot&name=x", 400, "kind"),
            (body.clone(), "kind=volume", 400, "name"),
            (body.clone(), "kind=volume&name=x&extra=1", 400, "extra"),
            (Vec::new(), "kind=volume&name=x", 422, "empty"),
            (big, "kind=volume&name=big", 413, ""),
        ];
        for (body, query, status, message) in cases {
            let r = upload(body, query).await.unwrap();
            assert_eq!(r.status(), status, "{query}");
            let text = r.text().await.unwrap();
            assert!(text.contains(message), "{query}: {text}");
        }
        let r = client
            .get(s.url("/api/v1/assets/..%2F..%2Fetc"))
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 404);
        let metrics = client
            .get(s.url("/metrics"))
            .send()
            .await
            .unwrap()
            .text()
            .await
            .unwrap();
        assert!(metrics.contains("mesobake_uploads_total 1\n"), "{metrics}");
    }
}

#[tokio::test]
async fn packages_download_with_etags_and_ranges() {
    let dir = tempfile::tempdir().unwrap();
    for url in database_urls(dir.path(), "packages").await {
        let data = tempfile::tempdir().unwrap();
        let s = TestServer::start(&url, data.path(), 1 << 20).await;
        let bytes: Vec<u8> = (0..100_000u32).map(|i| (i * 7 % 251) as u8).collect();
        let digest = s.state.blobs.put(&bytes).unwrap();
        s.state
            .db
            .insert_package(&PackageRow {
                digest: digest.clone(),
                bytes: bytes.len() as i64,
                manifest: serde_json::json!({}),
                created_ms: now_ms(),
            })
            .await
            .unwrap();
        let client = reqwest::Client::new();
        let path = s.url(&format!("/api/v1/packages/{digest}"));
        let r = client.get(&path).send().await.unwrap();
        assert_eq!(r.status(), 200);
        let etag = r.headers()["etag"].to_str().unwrap().to_owned();
        assert_eq!(etag, format!("\"{digest}\""));
        assert!(
            r.headers()["cache-control"]
                .to_str()
                .unwrap()
                .contains("immutable")
        );
        assert_eq!(r.bytes().await.unwrap().as_ref(), &bytes[..]);
        let r = client
            .get(&path)
            .header("if-none-match", &etag)
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 304);
        let r = client
            .get(&path)
            .header("range", "bytes=1000-1999")
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 206);
        assert_eq!(r.headers()["content-range"], "bytes 1000-1999/100000");
        assert_eq!(r.bytes().await.unwrap().as_ref(), &bytes[1000..2000]);
        let r = client
            .get(&path)
            .header("range", "bytes=200000-")
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 416);
        for missing in ["0".repeat(64), "not-a-digest".into()] {
            let r = client
                .get(s.url(&format!("/api/v1/packages/{missing}")))
                .send()
                .await
                .unwrap();
            assert_eq!(r.status(), 404);
        }
        assert_eq!(
            client.get(s.url("/healthz")).send().await.unwrap().status(),
            200
        );
        assert_eq!(
            client.get(s.url("/readyz")).send().await.unwrap().status(),
            200
        );
        let doc: serde_json::Value = client
            .get(s.url("/api/v1/openapi.json"))
            .send()
            .await
            .unwrap()
            .json()
            .await
            .unwrap();
        assert!(doc["paths"]["/api/v1/assets"]["post"].is_object(), "{doc}");
        assert!(doc["paths"]["/api/v1/packages/{digest}"]["get"].is_object());
    }
}

#[tokio::test]
async fn api_keys_guard_the_api_by_scope() {
    let dir = tempfile::tempdir().unwrap();
    for url in database_urls(dir.path(), "keys").await {
        let data = tempfile::tempdir().unwrap();
        let s = TestServer::start_with(&url, data.path(), 1 << 20, |c| c.require_keys = true).await;
        use mesobake_server::auth::Scope;
        let reader = s
            .state
            .db
            .create_api_key(&[Scope::Read], "reader")
            .await
            .unwrap();
        let uploader = s
            .state
            .db
            .create_api_key(&[Scope::Upload, Scope::Read], "ci")
            .await
            .unwrap();
        let client = reqwest::Client::new();
        let body = volume_bytes(SampleKind::Grid, 16);
        let post = |key: Option<&str>| {
            let mut r = client
                .post(s.url("/api/v1/assets?kind=volume&name=g.mbvol"))
                .body(body.clone());
            if let Some(k) = key {
                r = r.bearer_auth(k);
            }
            r.send()
        };
        assert_eq!(post(None).await.unwrap().status(), 401);
        assert_eq!(post(Some("mbk_0_forged")).await.unwrap().status(), 401);
        let r = post(Some(&reader)).await.unwrap();
        assert_eq!(r.status(), 403);
        assert!(r.text().await.unwrap().contains("upload scope"));
        let r = post(Some(&uploader)).await.unwrap();
        assert_eq!(r.status(), 201);
        let id = r.json::<serde_json::Value>().await.unwrap()["id"]
            .as_str()
            .unwrap()
            .to_owned();
        let get = |key: Option<&str>| {
            let mut r = client.get(s.url(&format!("/api/v1/assets/{id}")));
            if let Some(k) = key {
                r = r.bearer_auth(k);
            }
            r.send()
        };
        assert_eq!(get(None).await.unwrap().status(), 401);
        assert_eq!(get(Some(&reader)).await.unwrap().status(), 200);
        let r = client
            .post(s.url("/api/v1/jobs"))
            .bearer_auth(&uploader)
            .json(&serde_json::json!({}))
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 403, "bake needs the bake scope");
        // Public routes stay public; package downloads are public by default.
        for path in ["/healthz", "/api/v1/openapi.json", "/"] {
            assert_eq!(
                client.get(s.url(path)).send().await.unwrap().status(),
                200,
                "{path}"
            );
        }
        let r = client
            .get(s.url(&format!("/api/v1/packages/{}", "0".repeat(64))))
            .send()
            .await
            .unwrap();
        assert_eq!(
            r.status(),
            404,
            "a public package route answers without a key"
        );
        // Only hashes are stored.
        let stored: Vec<String> = sqlx::query_scalar("SELECT key_hash FROM api_keys")
            .fetch_all(&s.state.db.pool)
            .await
            .unwrap();
        assert!(
            stored
                .iter()
                .all(|h| h.len() == 64 && *h != reader && *h != uploader)
        );
    }
}

#[tokio::test]
async fn malformed_requests_get_a_4xx_with_a_message() {
    let dir = tempfile::tempdir().unwrap();
    let url = database_urls(dir.path(), "malformed").await.remove(0);
    let data = tempfile::tempdir().unwrap();
    let s = TestServer::start(&url, data.path(), 1 << 16).await;
    let client = reqwest::Client::new();
    let json = |body: Vec<u8>| {
        client
            .post(s.url("/api/v1/jobs"))
            .header("content-type", "application/json")
            .body(body)
            .send()
    };
    let cases: Vec<(Vec<u8>, u16)> = vec![
        (b"{\"scene\": \xff\xfe}".to_vec(), 400), // invalid UTF-8
        (b"[1, 2".to_vec(), 400),                 // truncated JSON
        (b"{\"scene\": 3}".to_vec(), 422),        // wrong type
        (format!("[{}]", "0,".repeat(40_000) + "0").into_bytes(), 413), // over the body limit
    ];
    for (body, status) in cases {
        let r = json(body).await.unwrap();
        assert_eq!(r.status(), status);
        assert!(!r.text().await.unwrap().is_empty(), "a message");
    }
    for path in [
        "/api/v1/assets/..%2F..%2Fetc%2Fpasswd",
        "/api/v1/packages/%2e%2e%2f%2e%2e",
        "/api/v1/jobs/..%2Fjobs/cancel",
        "/api/v1/packages/..%2F..%2Fblobs/manifest",
    ] {
        let r = client.get(s.url(path)).send().await.unwrap();
        assert!(r.status().is_client_error(), "{path}: {}", r.status());
    }
    // A scene whose effects contradict each other is refused with the scene's own message.
    let gi_job = serde_json::json!({ "scene": {
        "base_mesh": { "builtin": { "plane": {} } },
        "mesostructure": { "sample": "bark" },
        "shell": { "thickness": 0.1, "tiles_per_uv": [2, 2] },
        "camera": { "eye": [0, 2, 2], "target": [0, 0, 0], "fov_y_degrees": 45, "width": 8, "height": 8 },
        "environment": { "sky": { "overcast": { "zenith": [1, 1, 1], "ground": [0.2, 0.2, 0.2] } } },
        "effects": ["environment_gloss"]
    } });
    let r = client
        .post(s.url("/api/v1/jobs"))
        .json(&gi_job)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 422);
    assert!(
        r.text()
            .await
            .unwrap()
            .contains("refine environment_lighting")
    );
    let r = client
        .post(s.url("/api/v1/jobs/..%2F..%2Fx/cancel"))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 404);
}
