//! Bake jobs through the API on both database backends: planning, deduplication, progress
//! events, cancellation mid-bake, and a dead worker's job taken over after its lease.

use crate::server_harness::{TestServer, database_urls};
use mesobake_bake::mesostructure::samples::{self, SampleKind};
use mesobake_bake::mesostructure::volume_format;
use mesobake_bake::package::Package;
use mesobake_core::limits::Limits;
use mesobake_package::grid::Dims;
use mesobake_server::spawn_workers;
use object_store::ObjectStoreExt;
use serde_json::{Value, json};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

fn scene(volume: &str, res: [u32; 3], dirs: [u32; 2]) -> Value {
    json!({
        "base_mesh": { "builtin": { "plane": { "size": 2.0, "segments": 8 } } },
        "mesostructure": { "volume": volume },
        "resolution": res,
        "directions": dirs,
        "shell": { "thickness": 0.1, "tiles_per_uv": [4, 4] },
        "camera": { "eye": [0, 2, 2], "target": [0, 0, 0], "fov_y_degrees": 45, "width": 64, "height": 64 },
        "effects": ["silhouettes"]
    })
}

async fn upload(s: &TestServer, kind: SampleKind, res: [u32; 3]) -> String {
    let v = samples::volume(
        kind,
        Dims::new(res[0], res[1], res[2]).unwrap(),
        &Limits::default(),
    )
    .unwrap();
    let r = reqwest::Client::new()
        .post(s.url("/api/v1/assets?kind=volume&name=v.mbvol"))
        .body(volume_format::encode(&v))
        .send()
        .await
        .unwrap();
    assert!(r.status().is_success());
    r.json::<Value>().await.unwrap()["id"]
        .as_str()
        .unwrap()
        .to_owned()
}

/// Uploads a 16×16×8 grid, submits its job and returns the job's id (no worker runs yet).
async fn queue_grid_job(s: &TestServer) -> String {
    let volume = upload(s, SampleKind::Grid, [16, 16, 8]).await;
    let (_, queued) = submit(s, &json!({ "scene": scene(&volume, [16, 16, 8], [8, 16]) })).await;
    queued["id"].as_str().unwrap().to_owned()
}

async fn submit(s: &TestServer, body: &Value) -> (u16, Value) {
    let r = reqwest::Client::new()
        .post(s.url("/api/v1/jobs"))
        .json(body)
        .send()
        .await
        .unwrap();
    let status = r.status().as_u16();
    (status, r.json().await.unwrap_or(Value::Null))
}

async fn job(s: &TestServer, id: &str) -> Value {
    reqwest::get(s.url(&format!("/api/v1/jobs/{id}")))
        .await
        .unwrap()
        .json()
        .await
        .unwrap()
}

/// The package of succeeded job `done`, downloaded and parsed.
async fn fetch_package(s: &TestServer, done: &Value) -> Package {
    let digest = done["package_digest"].as_str().unwrap();
    let bytes = reqwest::get(s.url(&format!("/api/v1/packages/{digest}")))
        .await
        .unwrap()
        .bytes()
        .await
        .unwrap();
    Package::parse(bytes.to_vec()).unwrap()
}

async fn wait_for(s: &TestServer, id: &str, until: impl Fn(&Value) -> bool) -> Value {
    let start = Instant::now();
    loop {
        let j = job(s, id).await;
        if until(&j) {
            return j;
        }
        assert!(start.elapsed() < Duration::from_secs(120), "timed out: {j}");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

/// Job `id` once it has ended (succeeded, failed or cancelled).
async fn wait_until_ended(s: &TestServer, id: &str) -> Value {
    wait_for(s, id, |j| j["state"] != "queued" && j["state"] != "running").await
}

/// Submits `spec`, waits for its job to end and asserts that it succeeded.
async fn bakes(s: &TestServer, spec: &Value) -> Value {
    let (_, queued) = submit(s, spec).await;
    let done = wait_until_ended(s, queued["id"].as_str().unwrap()).await;
    assert_eq!(done["state"], "succeeded", "{done}");
    done
}

/// The manifest and the package (of any kind) of succeeded job `done`, downloaded.
async fn fetch_any(s: &TestServer, done: &Value) -> (Value, mesobake_bake::package::AnyPackage) {
    let digest = done["package_digest"].as_str().unwrap();
    let manifest: Value = reqwest::get(s.url(&format!("/api/v1/packages/{digest}/manifest")))
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    let bytes = reqwest::get(s.url(&format!("/api/v1/packages/{digest}")))
        .await
        .unwrap()
        .bytes()
        .await
        .unwrap();
    let package = mesobake_bake::package::AnyPackage::parse(bytes.to_vec()).unwrap();
    (manifest, package)
}

/// The preview of `scene` (which must succeed): the technique that drew it and the PNG.
async fn preview_png(s: &TestServer, scene: &Value) -> (String, Vec<u8>) {
    let r = reqwest::Client::new()
        .post(s.url("/api/v1/preview"))
        .json(&json!({ "scene": scene }))
        .send()
        .await
        .unwrap();
    let (status, technique) = (r.status(), r.headers().get("x-mesobake-technique").cloned());
    let png = r.bytes().await.unwrap().to_vec();
    assert_eq!(status, 200, "{}", String::from_utf8_lossy(&png));
    (technique.unwrap().to_str().unwrap().to_owned(), png)
}

/// Asserts that `png`, the server's preview of `scene`, is what the real-time pipeline's CPU
/// twin renders from `package` (≥ 35 dB, mask ≤ 0.5 %), and that both show the mesostructure
/// in more than a tenth of the pixels of the 48² image.
fn assert_previews_as_its_cpu_twin(
    png: &[u8],
    scene: &Value,
    package: &mesobake_bake::package::AnyPackage,
    dir: &std::path::Path,
) {
    use mesobake_render::image::{Image, compare};
    use mesobake_scene::preview::render_on_cpu;
    use mesobake_scene::{LoadedScene, Scene};
    let shown = dir.join("preview.png");
    std::fs::write(&shown, png).unwrap();
    let shown = Image::read(&shown).unwrap();
    let scene = Scene::from_json(&scene.to_string()).unwrap();
    let loaded = LoadedScene::load(scene, dir, &Limits::default()).unwrap();
    let expected = render_on_cpu(&loaded, package, &()).unwrap();
    let c = compare(&expected, &shown).unwrap();
    assert!(c.psnr_db >= 35.0 && c.mask_disagreement <= 0.005, "{c:?}");
    assert!(expected.hits() > 48 * 48 / 10 && shown.hits() > 48 * 48 / 10);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn jobs_bake_once_report_progress_and_reuse_results() {
    let dir = tempfile::tempdir().unwrap();
    for url in database_urls(dir.path(), "jobs").await {
        let data = tempfile::tempdir().unwrap();
        let s = TestServer::start(&url, data.path(), 1 << 24).await;
        let stop = Arc::new(AtomicBool::new(false));
        spawn_workers(&s.state, 1, &stop);
        let volume = upload(&s, SampleKind::Weave, [16, 16, 8]).await;
        let spec = json!({ "scene": scene(&volume, [16, 16, 8], [8, 16]), "codec": "paper-svd", "rank": 4 });
        let (status, queued) = submit(&s, &spec).await;
        assert_eq!(status, 202, "{url}: {queued}");
        let id = queued["id"].as_str().unwrap().to_owned();
        let skipped: Vec<&str> = queued["plan"]["skipped"]
            .as_array()
            .unwrap()
            .iter()
            .map(|k| k["stage"].as_str().unwrap())
            .collect();
        assert!(
            skipped.contains(&"bake_rtv") && skipped.contains(&"bake_prt"),
            "{queued}"
        );
        // The event stream ends with the final state.
        let events = reqwest::get(s.url(&format!("/api/v1/jobs/{id}/events")))
            .await
            .unwrap()
            .text()
            .await
            .unwrap();
        let last = events
            .lines()
            .filter_map(|l| l.strip_prefix("data: "))
            .next_back()
            .unwrap();
        let done: Value = serde_json::from_str(last).unwrap();
        assert_eq!(done["state"], "succeeded", "{done}");
        assert_eq!(done["progress"], 1.0);
        assert_eq!(done["stage"], "store");
        assert_eq!(done["attempts"], 1);
        assert!(
            done["timings"]["bake_gdm"].as_f64().unwrap() > 0.0,
            "{done}"
        );
        let package = fetch_package(&s, &done).await;
        assert_eq!(package.dims(), Dims::new(16, 16, 8).unwrap());
        assert_eq!(package.manifest().gdm.as_ref().unwrap().rank, 4);
        // Identical inputs: the same job, not a second bake; a different camera changes
        // nothing a package holds.
        let (status, again) = submit(&s, &spec).await;
        assert_eq!((status, &again["id"]), (200, &json!(id)));
        let mut moved = spec.clone();
        moved["scene"]["camera"]["eye"] = json!([1, 3, 2]);
        assert_eq!(submit(&s, &moved).await.1["id"], json!(id));
        assert_eq!(s.jobs().await.len(), 1);

        // Bad submissions: 4xx naming the problem, nothing queued.
        let mut wrong_kind = spec.clone();
        wrong_kind["scene"]["mesostructure"] = json!({ "tile": volume });
        let mut unknown = spec.clone();
        unknown["scene"]["mesostructure"] = json!({ "volume": "0".repeat(64) });
        let mut traversal = spec.clone();
        traversal["scene"]["mesostructure"] = json!({ "volume": "../../etc/passwd" });
        let mut bad_scene = spec.clone();
        bad_scene["scene"]["shell"]["thickness"] = json!(-1.0);
        let mut extra = spec.clone();
        extra["priority"] = json!(1);
        for (body, want) in [
            (
                wrong_kind,
                "is a volume, but the scene uses it as a mesh_tile",
            ),
            (unknown, "not the digest of an uploaded volume"),
            (traversal, "not the digest of an uploaded volume"),
            (bad_scene, "thickness"),
            (extra, "unknown field `priority`"),
        ] {
            let (status, answer) = submit(&s, &body).await;
            assert_eq!(status, 422, "{want}: {answer}");
            assert!(answer["error"].as_str().unwrap().contains(want), "{answer}");
        }
        let client = reqwest::Client::new();
        let r = client
            .post(s.url("/api/v1/jobs"))
            .header("content-type", "application/json")
            .body("{not json")
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 400);
        let r = client
            .post(s.url("/api/v1/jobs"))
            .header("content-type", "text/plain")
            .body(spec.to_string())
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 415);
        for path in [
            "/api/v1/jobs/nope",
            "/api/v1/jobs/00000000000000000000000000000000",
        ] {
            assert_eq!(reqwest::get(s.url(path)).await.unwrap().status(), 404);
        }
        stop.store(true, std::sync::atomic::Ordering::Relaxed);
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_gi_job_bakes_the_radiance_transfer_its_effects_call_for() {
    let dir = tempfile::tempdir().unwrap();
    let url = &database_urls(dir.path(), "gi").await[0];
    let data = tempfile::tempdir().unwrap();
    let s = TestServer::start(url, data.path(), 1 << 24).await;
    let stop = Arc::new(AtomicBool::new(false));
    spawn_workers(&s.state, 1, &stop);
    let mut scene = json!({
        "base_mesh": { "builtin": { "plane": { "size": 2.0, "segments": 8 } } },
        "mesostructure": { "sample": "weave" },
        "resolution": [16, 16, 8],
        "directions": [8, 16],
        "shell": { "thickness": 0.1, "tiles_per_uv": [4, 4] },
        "material": { "albedo": [0.7, 0.7, 0.7], "specular": [0.2, 0.2, 0.2], "shininess": 16 },
        "camera": { "eye": [0, 2, 2], "target": [0, 0, 0], "fov_y_degrees": 45, "width": 64, "height": 64 },
        "environment": { "exr": "sky.exr" },
        "effects": ["environment_lighting", "macro_shadows", "environment_gloss"]
    });
    let (status, queued) = submit(&s, &json!({ "scene": scene })).await;
    assert_eq!(status, 202, "{queued}");
    assert_eq!(
        queued["plan"]["stages"],
        json!([
            "load",
            "bake_gdm",
            "occupancy",
            "bake_prt",
            "bake_rtv",
            "compress_rtv",
            "encode",
            "store"
        ])
    );
    let id = queued["id"].as_str().unwrap().to_owned();
    let done = wait_until_ended(&s, &id).await;
    assert_eq!(done["state"], "succeeded", "{done}");
    for stage in ["bake_prt", "bake_rtv", "compress_rtv"] {
        assert!(done["timings"][stage].as_f64().is_some(), "{stage}: {done}");
    }
    let package = fetch_package(&s, &done).await;
    let gi = package.manifest().gi.clone().expect("radiance transfer");
    assert!(gi.macro_shadows && gi.glossy.is_some(), "{gi:?}");
    // The environment is not in the package, so another one shares the job; a change of
    // material changes the RTV, so it does not.
    scene["environment"] =
        json!({ "sky": { "overcast": { "zenith": [1, 1, 1], "ground": [0, 0, 0] } } });
    let (_, same) = submit(&s, &json!({ "scene": scene })).await;
    assert_eq!(same["id"], id.as_str());
    // The preview renders the package under the scene's sky; an EXR environment, which the
    // server cannot take, is refused before any job is queued.
    let preview = |scene: &Value| {
        reqwest::Client::new()
            .post(s.url("/api/v1/preview"))
            .json(&json!({ "scene": scene }))
            .send()
    };
    if std::env::var("MESOBAKE_SKIP_GPU_TESTS").as_deref() != Ok("1") {
        let r = preview(&scene).await.unwrap();
        assert_eq!(r.status(), 200);
        assert_eq!(r.headers()["content-type"], "image/png");
    }
    let mut exr = scene.clone();
    exr["environment"] = json!({ "exr": "sky.exr" });
    let r = preview(&exr).await.unwrap();
    assert_eq!(r.status(), 422);
    assert!(r.text().await.unwrap().contains("EXR"));
    scene["material"]["albedo"] = json!([0.5, 0.5, 0.5]);
    let (_, other) = submit(&s, &json!({ "scene": scene })).await;
    assert_ne!(other["id"], id.as_str());
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_gltf_base_mesh_is_uploaded_by_content_and_bakes() {
    // Blender's GLB (tests/data/blender) as a base_mesh upload, one of its two materials
    // baked; a .gltf whose buffer is a file beside it cannot come in one upload.
    let dir = tempfile::tempdir().unwrap();
    let url = database_urls(dir.path(), "gltf").await.remove(0);
    let data = tempfile::tempdir().unwrap();
    let s = TestServer::start(&url, data.path(), 1 << 24).await;
    let stop = Arc::new(AtomicBool::new(false));
    spawn_workers(&s.state, 1, &stop);
    let blender = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/blender");
    let client = reqwest::Client::new();
    let upload = |body: Vec<u8>, name: &str| {
        client
            .post(s.url(&format!("/api/v1/assets?kind=base_mesh&name={name}")))
            .body(body)
            .send()
    };
    let r = upload(
        std::fs::read(blender.join("knight.glb")).unwrap(),
        "knight.glb",
    )
    .await
    .unwrap();
    assert_eq!(r.status(), 201);
    let asset: Value = r.json().await.unwrap();
    assert_eq!(asset["summary"]["triangles"], 256, "{asset}");
    let mut external: Value =
        serde_json::from_slice(&std::fs::read(blender.join("knight.gltf")).unwrap()).unwrap();
    external["buffers"][0]["uri"] = "knight.bin".into();
    let r = upload(external.to_string().into_bytes(), "knight.gltf")
        .await
        .unwrap();
    assert_eq!(r.status(), 422);
    assert!(r.text().await.unwrap().contains("an upload holds one file"));

    let spec = json!({ "scene": {
        "base_mesh": { "gltf": { "file": asset["id"], "material": "Chain" } },
        "mesostructure": { "sample": "chain" },
        "resolution": [16, 16, 8],
        "shell": { "thickness": 0.05, "tiles_per_uv": [4, 2] },
        "camera": { "eye": [0, 3, 3], "target": [0, 0, 0], "fov_y_degrees": 45, "width": 32, "height": 32 }
    }});
    bakes(&s, &spec).await;
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
}

/// Blender's knight (`tests/data/blender/knight.glb`) uploaded once, its two materials two
/// objects with a mesostructure each: the preview asks for both packages (409 naming every
/// object's job), `object-jobs` finds the same jobs, each object's job is the job of that
/// object as a scene of its own, and once baked the preview draws both together as the
/// composed CPU renderers do from the same packages (≥ 35 dB, mask ≤ 0.5 %). An object the
/// preview of several cannot draw, or an invalid one, is refused naming it, queuing nothing.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_scene_of_several_objects_bakes_a_job_per_object_and_previews_them_together() {
    if std::env::var("MESOBAKE_SKIP_GPU_TESTS").as_deref() == Ok("1") {
        eprintln!("SKIPPED: MESOBAKE_SKIP_GPU_TESTS=1");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let url = database_urls(dir.path(), "objects").await.remove(0);
    let data = tempfile::tempdir().unwrap();
    let s = TestServer::start(&url, data.path(), 1 << 24).await;
    let glb =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/blender/knight.glb");
    let client = reqwest::Client::new();
    let r = client
        .post(s.url("/api/v1/assets?kind=base_mesh&name=knight.glb"))
        .body(std::fs::read(&glb).unwrap())
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 201);
    let id = r.json::<Value>().await.unwrap()["id"].clone();
    let scene = |base: Value, leather: Value| {
        json!({
            "camera": { "eye": [0.3, 3.2, 2.4], "target": [0.25, 0.5, 0], "fov_y_degrees": 45, "width": 48, "height": 48 },
            "lights": [{ "point": { "position": [2, 4, 3], "intensity": [40, 40, 40] } },
                       { "ambient": { "radiance": [0.05, 0.05, 0.05] } }],
            "effects": ["shadows"],
            "resolution": [16, 16, 8],
            "shell": { "thickness": 0.06, "tiles_per_uv": [8, 4] },
            "objects": [{ "base_mesh": { "gltf": base },
                          "materials": { "Chain": { "mesostructure": { "sample": "chain" } },
                                         "Leather": leather } }]
        })
    };
    let leather = json!({ "mesostructure": { "sample": "weave" } });
    let knight = scene(id.clone(), leather.clone());
    let post = |path: &'static str, body: Value| client.post(s.url(path)).json(&body).send();
    let r = post("/api/v1/preview", json!({ "scene": knight }))
        .await
        .unwrap();
    assert_eq!(r.status(), 409);
    let waiting: Value = r.json().await.unwrap();
    let jobs = waiting["jobs"].as_array().unwrap();
    let names: Vec<&str> = jobs.iter().map(|j| j["name"].as_str().unwrap()).collect();
    assert_eq!(names, ["Chain", "Leather"], "{waiting}");
    assert_eq!(waiting["job"]["id"], jobs[0]["job"]["id"]);
    assert!(
        waiting["error"].as_str().unwrap().contains("\"Chain\""),
        "{waiting}"
    );
    let r = post("/api/v1/object-jobs", json!({ "scene": knight }))
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    let submitted: Value = r.json().await.unwrap();
    for (a, b) in submitted.as_array().unwrap().iter().zip(jobs) {
        assert_eq!((&a["name"], &a["job"]["id"]), (&b["name"], &b["job"]["id"]));
    }
    // The chain's job is the job of the chain as a scene of one object.
    let mut chain = knight.clone();
    let shared = chain.as_object_mut().unwrap();
    shared.remove("objects");
    shared.insert(
        "base_mesh".into(),
        json!({ "gltf": { "file": id, "material": "Chain" } }),
    );
    shared.insert("mesostructure".into(), json!({ "sample": "chain" }));
    let (status, alone) = submit(&s, &json!({ "scene": chain })).await;
    assert_eq!(
        (status, &alone["id"]),
        (200, &jobs[0]["job"]["id"]),
        "{alone}"
    );
    // A scene of several objects posted as one job says where it goes.
    let (status, refused) = submit(&s, &json!({ "scene": knight })).await;
    assert_eq!(status, 422);
    assert!(
        refused["error"].to_string().contains("/api/v1/object-jobs"),
        "{refused}"
    );
    // Refusals name the object and queue nothing.
    let before = s.jobs().await.len();
    let fur = scene(id.clone(), json!({ "mesostructure": { "medium": "fur" } }));
    let r = post("/api/v1/preview", json!({ "scene": fur }))
        .await
        .unwrap();
    assert_eq!(r.status(), 422);
    let e = r.json::<Value>().await.unwrap()["error"].to_string();
    assert!(e.contains("Leather") && e.contains("transparency"), "{e}");
    let invalid = scene(
        id.clone(),
        json!({ "mesostructure": { "sample": "weave" }, "shell": { "thickness": -1 } }),
    );
    for path in ["/api/v1/object-jobs", "/api/v1/preview"] {
        let r = post(path, json!({ "scene": invalid })).await.unwrap();
        assert_eq!(r.status(), 422, "{path}");
        let e = r.json::<Value>().await.unwrap()["error"].to_string();
        assert!(
            e.contains("Leather") && e.contains("thickness"),
            "{path}: {e}"
        );
    }
    assert_eq!(s.jobs().await.len(), before);

    let stop = Arc::new(AtomicBool::new(false));
    spawn_workers(&s.state, 1, &stop);
    let mut packages = Vec::new();
    for j in jobs {
        let done = wait_until_ended(&s, j["job"]["id"].as_str().unwrap()).await;
        assert_eq!(done["state"], "succeeded", "{done}");
        packages.push(fetch_any(&s, &done).await.1);
    }
    let (technique, png) = preview_png(&s, &knight).await;
    assert_eq!(technique, "gdm");
    // The composed CPU renderers on the downloaded packages, the scene's glTF read from disk.
    use mesobake_render::image::{Image, compare};
    use mesobake_scene::LoadedScene;
    use mesobake_scene::render::{RenderMethod, render_objects};
    let local = scene(json!(glb), leather);
    let loaded: Vec<LoadedScene> = mesobake_scene::objects::from_json(&local.to_string())
        .unwrap()
        .into_iter()
        .map(|o| LoadedScene::load(o.scene, dir.path(), &Limits::default()).unwrap())
        .collect();
    let given: Vec<Option<&mesobake_bake::package::AnyPackage>> =
        packages.iter().map(Some).collect();
    let methods = [RenderMethod::Gdm; 2];
    let expected = render_objects(&loaded, &methods, &given, &(), &Limits::default())
        .unwrap()
        .image;
    let shown = dir.path().join("preview.png");
    std::fs::write(&shown, &png).unwrap();
    let c = compare(&expected, &Image::read(&shown).unwrap()).unwrap();
    assert!(c.psnr_db >= 35.0 && c.mask_disagreement <= 0.005, "{c:?}");
    assert!(expected.hits() > 48 * 48 / 10, "{} hits", expected.hits());
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
}

/// An OpenVDB file OpenVDB wrote, uploaded as a volume, is stored imported: the `.mbvol`
/// `mesobake import` writes (its digest the asset's id, the same bytes), with what it was
/// imported from; the import's options come as query parameters and are refused for other
/// uploads; a grid it cannot import is a 422 naming it, storing nothing; the imported level
/// set bakes.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_openvdb_volume_upload_is_stored_imported_and_bakes() {
    let dir = tempfile::tempdir().unwrap();
    let url = database_urls(dir.path(), "vdb").await.remove(0);
    let data = tempfile::tempdir().unwrap();
    let s = TestServer::start(&url, data.path(), 1 << 24).await;
    let stop = Arc::new(AtomicBool::new(false));
    spawn_workers(&s.state, 1, &stop);
    let vdb = |name: &str| {
        std::fs::read(
            std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("tests/data/openvdb")
                .join(name),
        )
        .unwrap()
    };
    let client = reqwest::Client::new();
    let upload = |body: Vec<u8>, query: &str| {
        client
            .post(s.url(&format!("/api/v1/assets?{query}")))
            .body(body)
            .send()
    };
    let r = upload(vdb("sphere.vdb"), "kind=volume&name=sphere.vdb")
        .await
        .unwrap();
    assert_eq!(r.status(), 201);
    let asset: Value = r.json().await.unwrap();
    assert_eq!(asset["summary"]["dims"], json!([30, 30, 31]), "{asset}");
    assert_eq!(asset["summary"]["openvdb"]["grid"], "surface", "{asset}");
    let limits = mesobake_core::limits::Limits::default();
    let (volume, _) = mesobake_bake::mesostructure::openvdb::import(
        &vdb("sphere.vdb"),
        &Default::default(),
        &limits,
    )
    .unwrap();
    let mbvol = mesobake_bake::mesostructure::volume_format::encode(&volume);
    assert_eq!(asset["id"], blake3::hash(&mbvol).to_hex().to_string());
    assert_eq!(asset["bytes"], mbvol.len());
    let r = upload(vdb("sphere.vdb"), "kind=volume&name=again.vdb")
        .await
        .unwrap();
    assert_eq!(r.status(), 200, "the same import is the same asset");

    let r = upload(
        vdb("fog.vdb"),
        "kind=volume&name=fog.vdb&grid=density_half&res=16x16x8&density_scale=2",
    )
    .await
    .unwrap();
    assert_eq!(r.status(), 201);
    let fog: Value = r.json().await.unwrap();
    assert_eq!(fog["summary"]["dims"], json!([16, 16, 8]), "{fog}");
    assert_eq!(fog["summary"]["opacity"], true, "{fog}");
    assert_eq!(fog["summary"]["openvdb"]["color_grid"], "Cd", "{fog}");
    for (body, query, says) in [
        (
            vdb("fog.vdb"),
            "kind=volume&name=m.vdb&grid=mask",
            "Tree_bool_5_4_3",
        ),
        (
            vdb("fog.vdb"),
            "kind=volume&name=m.vdb&res=0x1x1",
            "resolution 0x1x1",
        ),
        (
            mbvol.clone(),
            "kind=volume&name=v.mbvol&grid=surface",
            "not an OpenVDB file",
        ),
        (
            b"v 0 0 0".to_vec(),
            "kind=mesh_tile&name=t.obj&grid=surface",
            "OpenVDB uploads of kind volume",
        ),
    ] {
        let r = upload(body, query).await.unwrap();
        assert_eq!(r.status(), 422, "{query}");
        let text = r.text().await.unwrap();
        assert!(text.contains(says), "{query}: {text}");
    }

    let spec = json!({ "scene": {
        "base_mesh": { "builtin": { "plane": { "amplitude": 0.1, "segments": 4 } } },
        "mesostructure": { "volume": asset["id"] },
        "resolution": [30, 30, 31],
        "shell": { "thickness": 0.2, "tiles_per_uv": [2, 2] },
        "camera": { "eye": [0, 2, 2], "target": [0, 0, 0], "fov_y_degrees": 45, "width": 32, "height": 32 }
    }});
    bakes(&s, &spec).await;
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cancellation_stops_a_running_bake() {
    let dir = tempfile::tempdir().unwrap();
    for url in database_urls(dir.path(), "cancel").await {
        let data = tempfile::tempdir().unwrap();
        let s = TestServer::start(&url, data.path(), 1 << 26).await;
        let stop = Arc::new(AtomicBool::new(false));
        spawn_workers(&s.state, 1, &stop);
        // A bake of a few seconds: the paper-svd codec bakes the GDM, which dominates (the
        // default occupancy codec bakes no GDM, and is done in a quarter of a second).
        let volume = upload(&s, SampleKind::Chain, [128, 128, 32]).await;
        let (_, queued) = submit(
            &s,
            &json!({
                "scene": scene(&volume, [128, 128, 32], [16, 32]),
                "codec": "paper-svd",
                "rank": 8
            }),
        )
        .await;
        let id = queued["id"].as_str().unwrap().to_owned();
        wait_for(&s, &id, |j| j["state"] == "running").await;
        let r = reqwest::Client::new()
            .post(s.url(&format!("/api/v1/jobs/{id}/cancel")))
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 200);
        let asked = Instant::now();
        let j = wait_for(&s, &id, |j| j["state"] != "running").await;
        assert_eq!(j["state"], "cancelled", "{j}");
        assert!(j["package_digest"].is_null());
        // Honoured within a second (heartbeats every 250 ms), with slack for the polling.
        assert!(
            asked.elapsed() < Duration::from_millis(1500),
            "took {:?}",
            asked.elapsed()
        );
        stop.store(true, std::sync::atomic::Ordering::Relaxed);
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_dead_workers_job_is_taken_over_and_finishes_once() {
    let dir = tempfile::tempdir().unwrap();
    for url in database_urls(dir.path(), "lease").await {
        let data = tempfile::tempdir().unwrap();
        let s = TestServer::start(&url, data.path(), 1 << 24).await;
        let id = queue_grid_job(&s).await;
        // A worker claims it with a short lease and dies.
        let claimed = s
            .state
            .db
            .claim_job("dead-worker", 300)
            .await
            .unwrap()
            .unwrap();
        assert_eq!((claimed.id.as_str(), claimed.attempt), (id.as_str(), 1));
        assert!(
            s.state.db.claim_job("other", 300).await.unwrap().is_none(),
            "claimed twice"
        );
        let stop = Arc::new(AtomicBool::new(false));
        spawn_workers(&s.state, 1, &stop);
        let j = wait_for(&s, &id, |j| j["state"] == "succeeded").await;
        assert_eq!(j["attempts"], 2, "{j}");
        // The dead worker coming back cannot finish it a second time.
        let late = s
            .state
            .db
            .finish_job(&id, "dead-worker", "failed", None, Some("late"), &json!({}))
            .await
            .unwrap();
        assert!(!late);
        assert_eq!(job(&s, &id).await["state"], "succeeded");
        stop.store(true, std::sync::atomic::Ordering::Relaxed);
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_job_whose_workers_keep_dying_fails_after_its_attempts_and_says_so() {
    // Three workers claim it and die (their leases expire); the fourth claim gives up
    // without running it, and the job shows the 3 attempts that ran (it showed 4 of 3).
    let dir = tempfile::tempdir().unwrap();
    for url in database_urls(dir.path(), "give_up").await {
        let data = tempfile::tempdir().unwrap();
        let s = TestServer::start(&url, data.path(), 1 << 24).await;
        let id = queue_grid_job(&s).await;
        for attempt in 1..=3 {
            let claimed = s.state.db.claim_job("dying", 1).await.unwrap().unwrap();
            assert_eq!(
                (claimed.id.as_str(), claimed.attempt),
                (id.as_str(), attempt)
            );
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        let stop = Arc::new(AtomicBool::new(false));
        spawn_workers(&s.state, 1, &stop);
        let j = wait_for(&s, &id, |j| j["state"] == "failed").await;
        assert_eq!(
            (j["attempts"].as_i64(), j["max_attempts"].as_i64()),
            (Some(3), Some(3)),
            "{j}"
        );
        assert!(
            j["error"]
                .as_str()
                .unwrap()
                .contains("gave up after 3 attempts"),
            "{j}"
        );
        stop.store(true, std::sync::atomic::Ordering::Relaxed);
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn previews_render_once_the_package_is_baked() {
    if std::env::var("MESOBAKE_SKIP_GPU_TESTS").as_deref() == Ok("1") {
        eprintln!("SKIPPED: MESOBAKE_SKIP_GPU_TESTS=1");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let url = database_urls(dir.path(), "preview").await.remove(0);
    let data = tempfile::tempdir().unwrap();
    let s = TestServer::start(&url, data.path(), 1 << 24).await;
    let volume = upload(&s, SampleKind::Weave, [16, 16, 8]).await;
    let spec =
        json!({ "scene": scene(&volume, [16, 16, 8], [8, 16]), "codec": "paper-svd", "rank": 4 });
    let client = reqwest::Client::new();
    let ask = || client.post(s.url("/api/v1/preview")).json(&spec).send();
    // No worker yet: the package is not baked, and the answer says which job bakes it.
    let r = ask().await.unwrap();
    assert_eq!(r.status(), 409);
    let answer: Value = r.json().await.unwrap();
    let id = answer["job"]["id"].as_str().unwrap().to_owned();
    let stop = Arc::new(AtomicBool::new(false));
    spawn_workers(&s.state, 1, &stop);
    let done = wait_for(&s, &id, |j| j["state"] == "succeeded").await;
    let r = ask().await.unwrap();
    assert_eq!(r.status(), 200);
    assert_eq!(r.headers()["content-type"], "image/png");
    let png = r.bytes().await.unwrap();
    let decoder = png::Decoder::new(std::io::Cursor::new(png.to_vec()));
    let info = decoder.read_info().unwrap().info().clone();
    assert_eq!((info.width, info.height), (64, 64));
    // The same scene again: the cached image, byte for byte.
    assert_eq!(ask().await.unwrap().bytes().await.unwrap(), png);
    let manifest: Value = reqwest::get(s.url(&format!(
        "/api/v1/packages/{}/manifest",
        done["package_digest"].as_str().unwrap()
    )))
    .await
    .unwrap()
    .json()
    .await
    .unwrap();
    assert_eq!(manifest["gdm"]["rank"], 4);
    let sample: Value = reqwest::get(s.url("/api/v1/scenes/sample"))
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert_eq!(sample["mesostructure"]["sample"], "chain");
    // The figures' codec table is the committed report, and on each of its scenes the
    // default codec meets the packages target against the uncompressed GDM.
    let codecs = reqwest::get(s.url("/api/v1/reports/codecs"))
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    let committed = concat!(env!("CARGO_MANIFEST_DIR"), "/docs/codecs.json");
    assert_eq!(codecs, std::fs::read_to_string(committed).unwrap());
    // The conformance matrix is the committed report, and it covers every shipped scene (a
    // scene added under scenes/ needs the report run again).
    let conformance = reqwest::get(s.url("/api/v1/reports/conformance"))
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    let committed = concat!(env!("CARGO_MANIFEST_DIR"), "/docs/conformance.json");
    assert_eq!(conformance, std::fs::read_to_string(committed).unwrap());
    let conformance: Value = serde_json::from_str(&conformance).unwrap();
    let mut measured: Vec<&str> = (conformance["truths"].as_array().unwrap().iter())
        .map(|t| t["scene"].as_str().unwrap())
        .collect();
    measured.sort();
    let scenes_dir = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes");
    let mut shipped: Vec<String> = (std::fs::read_dir(scenes_dir).unwrap())
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "json"))
        .map(|p| p.file_stem().unwrap().to_string_lossy().into_owned())
        .collect();
    shipped.sort();
    assert_eq!(measured, shipped);
    let codecs: Value = serde_json::from_str(&codecs).unwrap();
    let rows = codecs["rows"].as_array().unwrap();
    for scene in ["torus-chain", "plane-weave"] {
        let row = |codec: &str| {
            rows.iter()
                .find(|r| r["scene"] == scene && r["codec"] == codec)
                .unwrap_or_else(|| panic!("{scene}: no {codec} row"))
        };
        let (default, reference) = (row("occupancy"), row("uncompressed"));
        let f = |r: &Value, k: &str| r[k].as_f64().unwrap();
        assert!(
            f(default, "psnr_db") >= f(reference, "psnr_db") - 0.5,
            "{scene}"
        );
        assert!(
            f(default, "mask_disagreement") <= f(reference, "mask_disagreement") + 0.003,
            "{scene}"
        );
    }
    let page = reqwest::get(s.url("/"))
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    assert!(page.contains("mesobake"));
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
}

/// A server on the first database of `dir` (its blobs in `data`), its configuration changed
/// by `edit`, with a worker; and the job of a 16×16×8 weave it has baked.
async fn baked_weave_server(
    dir: &std::path::Path,
    data: &std::path::Path,
    test: &str,
    edit: impl FnOnce(&mut mesobake_server::config::ServerConfig),
) -> (TestServer, Value, Arc<AtomicBool>) {
    let url = database_urls(dir, test).await.remove(0);
    let s = TestServer::start_with(&url, data, 1 << 24, edit).await;
    let stop = Arc::new(AtomicBool::new(false));
    spawn_workers(&s.state, 1, &stop);
    let volume = upload(&s, SampleKind::Weave, [16, 16, 8]).await;
    let spec = json!({ "scene": scene(&volume, [16, 16, 8], [8, 16]) });
    let (_, queued) = submit(&s, &spec).await;
    wait_for(&s, queued["id"].as_str().unwrap(), |j| {
        j["state"] == "succeeded"
    })
    .await;
    (s, spec, stop)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_preview_past_its_deadline_is_abandoned_with_503() {
    if std::env::var("MESOBAKE_SKIP_GPU_TESTS").as_deref() == Ok("1") {
        eprintln!("SKIPPED: MESOBAKE_SKIP_GPU_TESTS=1");
        return;
    }
    let (dir, data) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let (s, spec, stop) = baked_weave_server(dir.path(), data.path(), "preview_deadline", |c| {
        c.preview_timeout_ms = 1;
        c.busy_wait_ms = 60_000;
    })
    .await;
    let client = reqwest::Client::new();
    for _ in 0..2 {
        let r = client
            .post(s.url("/api/v1/preview"))
            .json(&spec)
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 503);
        assert_eq!(r.headers()["retry-after"], "1");
        let answer: Value = r.json().await.unwrap();
        assert!(
            answer["error"]
                .as_str()
                .unwrap()
                .contains("preview_timeout_ms"),
            "{answer}"
        );
    }
    let metrics = reqwest::get(s.url("/metrics"))
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    assert!(
        metrics.contains("mesobake_preview_cache_misses_total 2"),
        "{metrics}"
    );
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_abandoned_preview_is_cancelled_and_frees_the_gpu_at_once() {
    // A 2048² preview at 16 samples per pixel renders for tens of seconds on a software
    // driver or the CPU twin. Whether its client goes away or its deadline passes, it must
    // stop within a frame (a tile), so that the next preview gets the GPU before its
    // busy_wait_ms runs out; an abandoned render used to keep the GPU to its end.
    if std::env::var("MESOBAKE_SKIP_GPU_TESTS").as_deref() == Ok("1") {
        eprintln!("SKIPPED: MESOBAKE_SKIP_GPU_TESTS=1");
        return;
    }
    let (dir, data) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let (s, light, stop) = baked_weave_server(dir.path(), data.path(), "preview_cancel", |c| {
        c.preview_timeout_ms = 3_000;
        c.busy_wait_ms = 4_000;
        c.max_image_side = 8192;
    })
    .await;
    let client = reqwest::Client::new();
    let preview = |spec: &Value, side: u32| {
        let mut spec = spec.clone();
        spec["scene"]["camera"]["width"] = side.into();
        spec["scene"]["camera"]["height"] = side.into();
        client.post(s.url("/api/v1/preview")).json(&spec)
    };
    // Warm up the device, so that opening it is not part of what is timed below.
    assert_eq!(preview(&light, 8).send().await.unwrap().status(), 200);
    let mut heavy = light.clone();
    heavy["scene"]["camera"]["samples_per_pixel"] = 16.into();

    // The client gives up after a second: the render is cancelled with it.
    let cut = preview(&heavy, 2048)
        .timeout(Duration::from_secs(1))
        .send()
        .await;
    assert!(cut.is_err_and(|e| e.is_timeout()));
    let start = Instant::now();
    let r = preview(&light, 32).send().await.unwrap();
    assert_eq!(r.status(), 200, "{:?}", r.text().await);
    let after_disconnect = start.elapsed();

    // The deadline passes: 503, and the render is cancelled.
    let r = preview(&heavy, 2047).send().await.unwrap();
    assert_eq!(r.status(), 503);
    let answer: Value = r.json().await.unwrap();
    assert!(
        answer["error"]
            .as_str()
            .unwrap()
            .contains("preview_timeout_ms"),
        "{answer}"
    );
    let start = Instant::now();
    let r = preview(&light, 33).send().await.unwrap();
    assert_eq!(r.status(), 200, "{:?}", r.text().await);
    let after_deadline = start.elapsed();
    eprintln!(
        "next preview after a disconnect {after_disconnect:?}, after a deadline {after_deadline:?}"
    );
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_ci_client_bakes_on_the_server_and_verifies_downloads() {
    let dir = tempfile::tempdir().unwrap();
    let url = database_urls(dir.path(), "client").await.remove(0);
    let data = tempfile::tempdir().unwrap();
    let s = TestServer::start_with(&url, data.path(), 1 << 24, |c| c.require_keys = true).await;
    let key = s
        .state
        .db
        .create_api_key(
            &[
                mesobake_server::auth::Scope::Upload,
                mesobake_server::auth::Scope::Bake,
                mesobake_server::auth::Scope::Read,
            ],
            "ci",
        )
        .await
        .unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    spawn_workers(&s.state, 1, &stop);
    let input = dir.path().join("grid.mbvol");
    let v = samples::volume(
        SampleKind::Grid,
        Dims::new(16, 16, 8).unwrap(),
        &Limits::default(),
    )
    .unwrap();
    volume_format::write(&v, &input).unwrap();
    let out = dir.path().join("grid.mbpkg");
    let server = format!("http://{}", s.addr);
    let run = |args: Vec<String>, key: Option<String>| {
        tokio::task::spawn_blocking(move || {
            let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_mesobake"));
            c.args(&args);
            if let Some(k) = key {
                c.env("MESOBAKE_API_KEY", k);
            }
            c.output().unwrap()
        })
    };
    let args: Vec<String> = [
        "bake",
        "--server",
        &server,
        "--input",
        input.to_str().unwrap(),
        "--dirs",
        "8x16",
        "--gdm-codec",
        "paper-svd",
        "--rank",
        "3",
        "--out",
        out.to_str().unwrap(),
        "--json",
    ]
    .map(String::from)
    .to_vec();
    let o = run(args.clone(), Some(key.clone())).await.unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let summary: Value = serde_json::from_slice(&o.stdout).unwrap();
    let digest = summary["digest"].as_str().unwrap().to_owned();
    let bytes = std::fs::read(&out).unwrap();
    assert_eq!(mesobake_server::blobs::key_of(&bytes), digest);
    assert_eq!(
        Package::parse(bytes.clone())
            .unwrap()
            .manifest()
            .gdm
            .as_ref()
            .unwrap()
            .rank,
        3
    );
    // Without a key the server refuses, and the client says so.
    let o = run(args, None).await.unwrap();
    assert!(!o.status.success());
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("401"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    // fetch: the same bytes, verified; an unknown digest fails clearly.
    let fetched = dir.path().join("fetched.mbpkg");
    let o = run(
        [
            "fetch",
            "--server",
            &server,
            &digest,
            "--out",
            fetched.to_str().unwrap(),
        ]
        .map(String::from)
        .to_vec(),
        Some(key.clone()),
    )
    .await
    .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(std::fs::read(&fetched).unwrap(), bytes);
    // Under a memory limit below the download (refused from its Content-Length) or below
    // what reading it takes (the file fits, its decoded sections do not): refused by name,
    // and the file already there is left as it was.
    for limit in [bytes.len() as u64 - 1, bytes.len() as u64] {
        let o = run(
            [
                "--memory-limit",
                &limit.to_string(),
                "fetch",
                "--server",
                &server,
                &digest,
                "--out",
                fetched.to_str().unwrap(),
            ]
            .map(String::from)
            .to_vec(),
            Some(key.clone()),
        )
        .await
        .unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{stderr}");
        assert!(
            stderr.contains(&format!("over the memory limit of {limit} bytes")),
            "{stderr}"
        );
        assert_eq!(std::fs::read(&fetched).unwrap(), bytes);
    }
    let missing = "1".repeat(64);
    let o = run(
        [
            "fetch",
            "--server",
            &server,
            &missing,
            "--out",
            fetched.to_str().unwrap(),
        ]
        .map(String::from)
        .to_vec(),
        Some(key),
    )
    .await
    .unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("404"));
    assert_eq!(
        std::fs::read(&fetched).unwrap(),
        bytes,
        "a failed fetch leaves the file as it was"
    );
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
}

/// A `side`² 16-bit grayscale PNG of periodic bumps.
fn height_field_png(side: u32) -> Vec<u8> {
    let mut out = Vec::new();
    let mut encoder = png::Encoder::new(&mut out, side, side);
    encoder.set_color(png::ColorType::Grayscale);
    encoder.set_depth(png::BitDepth::Sixteen);
    let tau = std::f64::consts::TAU;
    let data: Vec<u8> = (0..side * side)
        .flat_map(|p| {
            let (u, v) = (
                (p % side) as f64 / side as f64,
                (p / side) as f64 / side as f64,
            );
            let h = 0.5 + 0.3 * (tau * u).sin() * (tau * v).cos();
            ((h * 65535.0) as u16).to_be_bytes()
        })
        .collect();
    encoder
        .write_header()
        .unwrap()
        .write_image_data(&data)
        .unwrap();
    out
}

/// A moto S3 server on a free port (killed on drop), with its endpoint.
struct S3Server(std::process::Child, String);

impl Drop for S3Server {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Starts moto's S3 server with an empty bucket `bucket`, or `None` (skipping loudly) where
/// moto is not installed and `MESOBAKE_REQUIRE_S3` is not set.
async fn s3_server(bucket: &str) -> Option<S3Server> {
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let child = match std::process::Command::new("moto_server")
        .args(["-H", "127.0.0.1", "-p", &port.to_string()])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
    {
        Ok(child) => child,
        Err(e) if std::env::var("MESOBAKE_REQUIRE_S3").as_deref() == Ok("1") => {
            panic!("moto_server required (pip install 'moto[server]'): {e}")
        }
        Err(e) => {
            eprintln!("SKIPPED: the S3 test needs moto_server (pip install 'moto[server]'): {e}");
            return None;
        }
    };
    let server = S3Server(child, format!("http://127.0.0.1:{port}"));
    let client = reqwest::Client::new();
    let start = Instant::now();
    while client.get(&server.1).send().await.is_err() {
        assert!(
            start.elapsed() < Duration::from_secs(30),
            "moto did not start"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    let created = client
        .put(format!("{}/{bucket}", server.1))
        .send()
        .await
        .unwrap();
    assert!(created.status().is_success(), "{created:?}");
    Some(server)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_s3_blob_store_is_shared_by_servers_on_other_machines() {
    let Some(s3) = s3_server("mesobake-test").await else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let url = database_urls(dir.path(), "s3").await.remove(0);
    let on_s3 = |c: &mut mesobake_server::config::ServerConfig| {
        c.blob_url = "s3://mesobake-test/blobs".into();
        for (k, v) in [
            ("endpoint", s3.1.as_str()),
            ("allow_http", "true"),
            ("region", "us-east-1"),
            ("access_key_id", "test"),
            ("secret_access_key", "test"),
        ] {
            c.blob_options.insert(k.into(), v.into());
        }
    };
    // Machine A uploads and bakes.
    let data_a = tempfile::tempdir().unwrap();
    let a = TestServer::start_with(&url, data_a.path(), 1 << 24, on_s3).await;
    let stop = Arc::new(AtomicBool::new(false));
    spawn_workers(&a.state, 1, &stop);
    let volume = upload(&a, SampleKind::Chain, [16, 16, 8]).await;
    // The bake reads a height field (a bumpy 16-bit PNG) from the bucket.
    let r = reqwest::Client::new()
        .post(a.url("/api/v1/assets?kind=height_field&name=bumps.png"))
        .body(height_field_png(32))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 201);
    let heights: Value = r.json().await.unwrap();
    assert_eq!(heights["summary"]["size"], json!([32, 32]));
    let heights = heights["id"].as_str().unwrap().to_owned();
    let mut job_scene = scene("", [16, 16, 8], [4, 8]);
    job_scene["mesostructure"] = json!({ "height_field": heights });
    let (status, queued) = submit(&a, &json!({ "scene": job_scene })).await;
    assert_eq!(status, 202, "{queued}");
    let id = queued["id"].as_str().unwrap();
    let done = wait_until_ended(&a, id).await;
    assert_eq!(done["state"], "succeeded", "{done}");
    let digest = done["package_digest"].as_str().unwrap().to_owned();
    // The package and the upload are objects in the bucket, under the prefix.
    let bucket = object_store::aws::AmazonS3Builder::new()
        .with_bucket_name("mesobake-test")
        .with_endpoint(&s3.1)
        .with_allow_http(true)
        .with_region("us-east-1")
        .with_access_key_id("test")
        .with_secret_access_key("test")
        .build()
        .unwrap();
    let object = |key: &str| object_store::path::Path::from(format!("blobs/{key}"));
    for key in [&digest, &volume, &heights] {
        let stored = bucket
            .get(&object(key))
            .await
            .unwrap()
            .bytes()
            .await
            .unwrap();
        assert_eq!(blake3::hash(&stored).to_hex().as_str(), key);
    }
    // Machine B, with an empty cache, serves the package and deduplicates the upload.
    let data_b = tempfile::tempdir().unwrap();
    let b = TestServer::start_with(&url, data_b.path(), 1 << 24, on_s3).await;
    let package = reqwest::get(b.url(&format!("/api/v1/packages/{digest}")))
        .await
        .unwrap();
    assert_eq!(package.status(), 200);
    Package::parse(package.bytes().await.unwrap().to_vec()).unwrap();
    assert!(
        data_b
            .path()
            .join("blobs")
            .join(&digest[..2])
            .join(&digest)
            .is_file()
    );
    assert_eq!(upload(&b, SampleKind::Chain, [16, 16, 8]).await, volume);
    // An object that no longer matches its key is refused, not served.
    bucket
        .put(&object(&digest), "not a package".into())
        .await
        .unwrap();
    let data_c = tempfile::tempdir().unwrap();
    let c = TestServer::start_with(&url, data_c.path(), 1 << 24, on_s3).await;
    let refused = reqwest::get(c.url(&format!("/api/v1/packages/{digest}")))
        .await
        .unwrap();
    assert_eq!(refused.status(), 500);
    assert!(
        refused
            .text()
            .await
            .unwrap()
            .contains("does not match its key")
    );
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_height_field_scene_bakes_a_vdm_package_and_previews_by_the_vdm_pipeline() {
    use mesobake_bake::package::AnyPackage;
    if std::env::var("MESOBAKE_SKIP_GPU_TESTS").as_deref() == Ok("1") {
        eprintln!("SKIPPED: MESOBAKE_SKIP_GPU_TESTS=1");
        return;
    }
    let scene = json!({
        "base_mesh": { "builtin": { "torus": { "segments": [24, 12] } } },
        "mesostructure": { "relief": "bumps" },
        "resolution": [16, 16, 8],
        "shell": { "thickness": 0.04, "tiles_per_uv": [8, 4] },
        "camera": { "eye": [0, 2, 2.5], "target": [0, 0, 0], "fov_y_degrees": 45, "width": 48, "height": 48 },
        "lights": [{ "point": { "position": [2, 4, 3], "intensity": [60, 60, 60] } }],
        "effects": ["silhouettes", "shadows"],
        "vdm": { "directions": [4, 8], "curvatures": 4 }
    });
    let dir = tempfile::tempdir().unwrap();
    for url in database_urls(dir.path(), "vdm_jobs").await {
        let data = tempfile::tempdir().unwrap();
        let s = TestServer::start(&url, data.path(), 1 << 24).await;
        // The GDM codec's options do not apply to a VDM package: refused by name.
        let (status, refused) = submit(
            &s,
            &json!({ "scene": scene, "codec": "paper-svd", "rank": 4 }),
        )
        .await;
        assert_eq!(status, 422, "{refused}");
        assert!(
            refused["error"]
                .as_str()
                .unwrap()
                .contains("the scene's technique is vdm"),
            "{refused}"
        );
        // auto chose VDM, and the plan runs only its stages.
        let (status, queued) = submit(&s, &json!({ "scene": scene })).await;
        assert_eq!(status, 202, "{queued}");
        assert_eq!(queued["plan"]["technique"]["technique"], "vdm", "{queued}");
        assert!(
            queued["plan"]["technique"]["reason"]
                .as_str()
                .unwrap()
                .starts_with("auto: a height field on a closed surface"),
            "{queued}"
        );
        assert_eq!(
            queued["plan"]["stages"],
            json!(["load", "bake_vdm", "compress_vdm", "encode", "store"])
        );
        // What a VDM package depends on: not the camera, but the VDM settings and the shell.
        let mut moved = scene.clone();
        moved["camera"]["eye"] = json!([0, 3, 1]);
        let (status, same) = submit(&s, &json!({ "scene": moved })).await;
        assert_eq!((status, &same["id"]), (200, &queued["id"]));
        for (key, value) in [
            ("vdm", json!({ "directions": [4, 8], "curvatures": 5 })),
            (
                "shell",
                json!({ "thickness": 0.05, "tiles_per_uv": [8, 4] }),
            ),
            ("technique", json!("gdm")),
        ] {
            let mut other = scene.clone();
            other[key] = value;
            let (status, job) = submit(&s, &json!({ "scene": other })).await;
            assert_eq!(status, 202, "{key}: {job}");
            assert_ne!(job["id"], queued["id"], "{key}");
        }
        let id = queued["id"].as_str().unwrap().to_owned();
        let stop = Arc::new(AtomicBool::new(false));
        spawn_workers(&s.state, 1, &stop);
        let done = wait_for(&s, &id, |j| j["state"] == "succeeded").await;
        assert!(
            done["timings"]["bake_vdm"].as_f64().unwrap() >= 0.0,
            "{done}"
        );
        assert!(done["timings"].get("bake_gdm").is_none(), "{done}");
        let (manifest, package) = fetch_any(&s, &done).await;
        assert_eq!(manifest["format"], "mesobake-vdm-package", "{manifest}");
        assert_eq!(manifest["bake"]["grid"]["n_curvature"], 4, "{manifest}");
        assert!(matches!(package, AnyPackage::Vdm(_)));

        // The preview draws it by the VDM pipeline, as its CPU specification does.
        let (technique, png) = preview_png(&s, &scene).await;
        assert_eq!(technique, "vdm");
        assert_previews_as_its_cpu_twin(&png, &scene, &package, data.path());
        stop.store(true, std::sync::atomic::Ordering::Relaxed);
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_translucent_scene_bakes_a_medium_package_once_for_every_base_mesh() {
    use mesobake_bake::package::AnyPackage;
    if std::env::var("MESOBAKE_SKIP_GPU_TESTS").as_deref() == Ok("1") {
        eprintln!("SKIPPED: MESOBAKE_SKIP_GPU_TESTS=1");
        return;
    }
    let scene = json!({
        "base_mesh": { "builtin": { "torus": { "segments": [16, 8] } } },
        "mesostructure": { "medium": "fur" },
        "resolution": [16, 16, 8],
        "shell": { "thickness": 0.15, "tiles_per_uv": [8, 4] },
        "camera": { "eye": [0, 2, 2.5], "target": [0, 0, 0], "fov_y_degrees": 45, "width": 48, "height": 48 },
        "lights": [{ "directional": { "direction": [-0.4, -1, -0.5], "irradiance": [2.5, 2.5, 2.5] } }],
        "effects": ["silhouettes", "shadows"],
        "transparency": { "mipmap": true }
    });
    let dir = tempfile::tempdir().unwrap();
    for url in database_urls(dir.path(), "medium_jobs").await {
        let data = tempfile::tempdir().unwrap();
        let s = TestServer::start(&url, data.path(), 1 << 24).await;
        // The GDM codec's options do not apply; asking a GDM of a medium is refused by name.
        let (status, refused) = submit(&s, &json!({ "scene": scene, "codec": "paper-svd" })).await;
        assert_eq!(status, 422, "{refused}");
        let e = refused["error"].as_str().unwrap();
        assert!(
            e.contains("the scene's technique is transparency"),
            "{refused}"
        );
        let mut gdm = scene.clone();
        gdm["technique"] = json!("gdm");
        let (status, refused) = submit(&s, &json!({ "scene": gdm })).await;
        assert_eq!(status, 422, "{refused}");
        assert!(
            refused["error"]
                .as_str()
                .unwrap()
                .contains("translucent medium"),
            "{refused}"
        );

        // auto chose the transparency technique; the plan bakes the medium and its mip-map.
        let (status, queued) = submit(&s, &json!({ "scene": scene })).await;
        assert_eq!(status, 202, "{queued}");
        let plan = &queued["plan"];
        assert_eq!(plan["technique"]["technique"], "transparency", "{queued}");
        assert_eq!(
            plan["stages"],
            json!(["load", "medium_mips", "encode", "store"])
        );
        let skipped: Vec<&str> = plan["skipped"]
            .as_array()
            .unwrap()
            .iter()
            .map(|k| k["stage"].as_str().unwrap())
            .collect();
        for stage in ["bake_gdm", "occupancy", "compress", "bake_rtv"] {
            assert!(skipped.contains(&stage), "{stage}: {plan}");
        }
        // An animated surface: another base mesh, shell and camera bake nothing new.
        let mut animated = scene.clone();
        animated["base_mesh"] =
            json!({ "builtin": { "torus": { "major_radius": 1.2, "segments": [20, 10] } } });
        animated["shell"]["thickness"] = json!(0.12);
        animated["camera"]["eye"] = json!([0, 3, 1]);
        let (status, same) = submit(&s, &json!({ "scene": animated })).await;
        assert_eq!((status, &same["id"]), (200, &queued["id"]), "{same}");
        // What the package holds does change it.
        for (key, value) in [
            ("transparency", json!({ "mipmap": false })),
            (
                "transparency",
                json!({ "mipmap": true, "quantization": "f32" }),
            ),
            ("mesostructure", json!({ "medium": "clouds" })),
        ] {
            let mut other = scene.clone();
            other[key] = value;
            let (status, job) = submit(&s, &json!({ "scene": other })).await;
            assert_eq!(status, 202, "{key}: {job}");
            assert_ne!(job["id"], queued["id"], "{key}");
        }

        // An uploaded volume with an opacity channel is found translucent from its header.
        let medium = mesobake_bake::mesostructure::media::volume(
            mesobake_bake::mesostructure::media::MediumKind::Clouds,
            Dims::new(16, 16, 8).unwrap(),
            &Limits::default(),
        )
        .unwrap();
        let r = reqwest::Client::new()
            .post(s.url("/api/v1/assets?kind=volume&name=clouds.mbvol"))
            .body(volume_format::encode(&medium))
            .send()
            .await
            .unwrap();
        assert!(r.status().is_success());
        let asset: Value = r.json().await.unwrap();
        let mut uploaded = scene.clone();
        uploaded["mesostructure"] = json!({ "volume": asset["id"] });
        let (status, job) = submit(&s, &json!({ "scene": uploaded })).await;
        assert_eq!(status, 202, "{job}");
        assert_eq!(
            job["plan"]["technique"]["technique"], "transparency",
            "{job}"
        );
        uploaded["technique"] = json!("gdm");
        let (status, refused) = submit(&s, &json!({ "scene": uploaded })).await;
        assert_eq!(status, 422, "{refused}");

        let id = queued["id"].as_str().unwrap().to_owned();
        let stop = Arc::new(AtomicBool::new(false));
        spawn_workers(&s.state, 1, &stop);
        let done = wait_for(&s, &id, |j| j["state"] == "succeeded").await;
        assert!(done["timings"].get("bake_gdm").is_none(), "{done}");
        let (manifest, package) = fetch_any(&s, &done).await;
        assert_eq!(manifest["format"], "mesobake-medium-package", "{manifest}");
        let levels = manifest["medium"]["levels"].as_array().unwrap();
        assert_eq!(levels.len(), 4, "16×16×8 halves to 2×2×1: {manifest}");
        assert!(matches!(package, AnyPackage::Medium(_)));

        // Every job baked (the other settings' too), so that only a new job could change the list.
        let start = Instant::now();
        let jobs_before = loop {
            let jobs: Value = reqwest::get(s.url("/api/v1/jobs"))
                .await
                .unwrap()
                .json()
                .await
                .unwrap();
            if jobs
                .as_array()
                .unwrap()
                .iter()
                .all(|j| j["state"] == "succeeded")
            {
                break jobs;
            }
            assert!(start.elapsed() < Duration::from_secs(120), "{jobs}");
            tokio::time::sleep(Duration::from_millis(50)).await;
        };
        // Both surfaces preview from that one package, as its CPU specification renders them.
        for shown_scene in [&scene, &animated] {
            let (technique, png) = preview_png(&s, shown_scene).await;
            assert_eq!(technique, "transparency");
            assert_previews_as_its_cpu_twin(&png, shown_scene, &package, data.path());
        }
        let jobs_after: Value = reqwest::get(s.url("/api/v1/jobs"))
            .await
            .unwrap()
            .json()
            .await
            .unwrap();
        assert_eq!(jobs_after, jobs_before, "the previews baked nothing more");
        stop.store(true, std::sync::atomic::Ordering::Relaxed);
    }
}

/// Runs the binary with `args` in `dir`, which must succeed.
fn cli(dir: &std::path::Path, args: &[&str]) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_mesobake"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_server_job_bakes_and_previews_what_the_cli_does_by_default() {
    // One default everywhere: a job with no codec options bakes the package `bake --scene`
    // writes, byte for byte; the server's preview is the CLI's `preview` of the scene, and
    // `render` (the CPU specification) draws the same image. torus-chain (its `balanced`
    // quality: shell shadows) and plane-weave (the paper's), at 96².
    if std::env::var("MESOBAKE_SKIP_GPU_TESTS").as_deref() == Ok("1") {
        eprintln!("SKIPPED: MESOBAKE_SKIP_GPU_TESTS=1");
        return;
    }
    use mesobake_render::image::{Image, compare};
    let dir = tempfile::tempdir().unwrap();
    let url = database_urls(dir.path(), "defaults").await.remove(0);
    let data = tempfile::tempdir().unwrap();
    let s = TestServer::start(&url, data.path(), 1 << 24).await;
    let stop = Arc::new(AtomicBool::new(false));
    spawn_workers(&s.state, 1, &stop);
    for name in ["torus-chain", "plane-weave"] {
        let shipped = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("scenes")
            .join(format!("{name}.json"));
        let mut scene: Value =
            serde_json::from_str(&std::fs::read_to_string(shipped).unwrap()).unwrap();
        scene["camera"]["width"] = 96.into();
        scene["camera"]["height"] = 96.into();
        let work = dir.path().join(name);
        std::fs::create_dir_all(&work).unwrap();
        std::fs::write(work.join("scene.json"), scene.to_string()).unwrap();
        let (status, queued) = submit(&s, &json!({ "scene": scene })).await;
        assert!(status == 200 || status == 201 || status == 202, "{queued}");
        let id = queued["id"].as_str().unwrap().to_owned();
        let done = wait_for(&s, &id, |j| j["state"] == "succeeded").await;
        let digest = done["package_digest"].as_str().unwrap();
        let served = reqwest::get(s.url(&format!("/api/v1/packages/{digest}")))
            .await
            .unwrap()
            .bytes()
            .await
            .unwrap();
        cli(
            &work,
            &["bake", "--scene", "scene.json", "--out", "cli.mbpkg"],
        );
        assert!(
            std::fs::read(work.join("cli.mbpkg")).unwrap() == served.as_ref(),
            "{name}: the job's package is not the CLI's"
        );
        let (_, png) = preview_png(&s, &scene).await;
        std::fs::write(work.join("server.png"), &png).unwrap();
        cli(
            &work,
            &["preview", "--scene", "scene.json", "--out", "preview.png"],
        );
        cli(
            &work,
            &["render", "--scene", "scene.json", "--out", "render.png"],
        );
        let image = |f: &str| Image::read(&work.join(f)).unwrap();
        let server = image("server.png");
        let same = compare(&image("preview.png"), &server).unwrap();
        assert!(same.psnr_db.is_infinite(), "{name}: {same:?}");
        let cpu = compare(&image("render.png"), &server).unwrap();
        eprintln!("{name}: render against the server's preview {cpu:?}");
        assert!(
            cpu.psnr_db >= 35.0 && cpu.mask_disagreement <= 0.005,
            "{name}: {cpu:?}"
        );
        assert!(server.hits() > 96 * 96 / 10, "{name}");
    }
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
}
