//! Running the server in-process against each database backend.
#![allow(dead_code)] // each test file uses part of it

use mesobake_core::limits::Limits;
use mesobake_server::{AppState, config::ServerConfig, open_state, serve_on};
use std::net::SocketAddr;

/// The PostgreSQL server of the test machine (trust authentication).
pub const POSTGRES_ADMIN_URL: &str = "postgres://postgres@127.0.0.1:5432/test";

/// A database for one test: a SQLite file in `dir`, or a fresh PostgreSQL database.
pub async fn database_urls(dir: &std::path::Path, test: &str) -> Vec<String> {
    let mut urls = vec![format!("sqlite://{}", dir.join("db.sqlite").display())];
    match sqlx::PgPool::connect(POSTGRES_ADMIN_URL).await {
        Ok(admin) => {
            let name = format!("mesobake_{test}_{}", std::process::id());
            // Earlier runs' databases of this test go first: exactly this test's name and a
            // process id (a LIKE prefix would also take, and drop, a running test's whose
            // name starts with this one's).
            let old: Vec<String> =
                sqlx::query_scalar("SELECT datname FROM pg_database WHERE datname ~ $1")
                    .bind(format!("^mesobake_{test}_[0-9]+$"))
                    .fetch_all(&admin)
                    .await
                    .unwrap();
            for db in old {
                let drop = format!("DROP DATABASE IF EXISTS {db} WITH (FORCE)");
                sqlx::query(sqlx::AssertSqlSafe(drop))
                    .execute(&admin)
                    .await
                    .unwrap();
            }
            sqlx::query(sqlx::AssertSqlSafe(format!("CREATE DATABASE {name}")))
                .execute(&admin)
                .await
                .unwrap();
            urls.push(format!("postgres://postgres@127.0.0.1:5432/{name}"));
        }
        Err(e) if std::env::var("MESOBAKE_REQUIRE_POSTGRES").as_deref() == Ok("1") => {
            panic!("PostgreSQL required but unreachable at {POSTGRES_ADMIN_URL}: {e}")
        }
        Err(e) => {
            eprintln!("SKIPPED the PostgreSQL backend: {POSTGRES_ADMIN_URL} unreachable: {e}")
        }
    }
    urls
}

/// A server listening on an ephemeral port.
pub struct TestServer {
    /// Its address.
    pub addr: SocketAddr,
    /// Its state (database and blob store), for checks behind the API.
    pub state: AppState,
}

impl TestServer {
    /// Starts a server over `database_url` with its blobs under `data_dir`.
    pub async fn start(
        database_url: &str,
        data_dir: &std::path::Path,
        max_upload: u64,
    ) -> TestServer {
        Self::start_with(database_url, data_dir, max_upload, |_| {}).await
    }

    /// [`TestServer::start`] with further changes to the configuration.
    pub async fn start_with(
        database_url: &str,
        data_dir: &std::path::Path,
        max_upload: u64,
        edit: impl FnOnce(&mut ServerConfig),
    ) -> TestServer {
        let mut config = ServerConfig::load(None).unwrap();
        config.database_url = database_url.into();
        config.data_dir = data_dir.into();
        config.max_upload_bytes = max_upload;
        config.max_json_bytes = config.max_json_bytes.min(max_upload);
        config.listen = "127.0.0.1:0".into();
        edit(&mut config);
        let state = open_state(&config, Limits::default()).await.unwrap();
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let addr = listener.local_addr().unwrap();
        tokio::spawn(serve_on(listener, state.clone(), std::future::pending()));
        TestServer { addr, state }
    }

    /// The URL of `path`.
    pub fn url(&self, path: &str) -> String {
        format!("http://{}{path}", self.addr)
    }

    /// Every job the server lists (`GET /api/v1/jobs`).
    pub async fn jobs(&self) -> Vec<serde_json::Value> {
        reqwest::get(self.url("/api/v1/jobs"))
            .await
            .unwrap()
            .json()
            .await
            .unwrap()
    }
}
