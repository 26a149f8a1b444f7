//! The server commands: `mesobake serve` (the HTTP API with its workers), `mesobake worker`
//! (workers only) and `mesobake keys` (API keys in the configured database).

use clap::Subcommand;
use mesobake_core::limits::Limits;
use mesobake_core::{Error, Result};
use mesobake_server::auth::Scope;
use mesobake_server::config::ServerConfig;
use mesobake_server::db::Db;
use std::path::PathBuf;

/// Options of `mesobake serve` and `mesobake worker`.
#[derive(clap::Args)]
pub struct ConfigArgs {
    /// A TOML file overriding config/default.toml (then MESOBAKE_* variables override it).
    #[arg(long)]
    config: Option<PathBuf>,
}

/// Runs the server until Ctrl-C or SIGTERM.
pub fn serve(args: ConfigArgs, limits: Limits) -> Result<()> {
    let config = ServerConfig::load(args.config.as_deref())?;
    run_service(mesobake_server::serve(config, limits))
}

/// Runs workers until Ctrl-C or SIGTERM.
pub fn worker(args: ConfigArgs, limits: Limits) -> Result<()> {
    let config = ServerConfig::load(args.config.as_deref())?;
    run_service(mesobake_server::work(config, limits))
}

/// A tokio runtime for the commands that talk to the server's database.
fn runtime() -> Result<tokio::runtime::Runtime> {
    tokio::runtime::Runtime::new()
        .map_err(|e| Error::InvalidParameter(format!("starting the runtime: {e}")))
}

/// Runs the server or the workers with logging to stderr. Bakes that were abandoned at
/// shutdown (their jobs handed back to the queue) are not waited for.
fn run_service(service: impl Future<Output = Result<()>>) -> Result<()> {
    tracing_subscriber::fmt()
        .with_max_level(tracing::Level::INFO)
        .with_writer(std::io::stderr)
        .init();
    let runtime = runtime()?;
    let result = runtime.block_on(service);
    runtime.shutdown_timeout(std::time::Duration::from_millis(100));
    result
}

/// `mesobake keys`.
#[derive(Subcommand)]
pub enum KeysCommand {
    /// Create a key with the given scopes.
    Create {
        /// Comma-separated scopes: upload, bake, read.
        #[arg(long)]
        scopes: String,
        /// A note saying whose key it is.
        #[arg(long, default_value = "")]
        label: String,
        /// The server's configuration file (for its database).
        #[arg(long)]
        config: Option<PathBuf>,
    },
    /// List the issued keys: id, scopes, label, issue time, whether revoked (never the
    /// keys themselves).
    List {
        /// The server's configuration file (for its database).
        #[arg(long)]
        config: Option<PathBuf>,
    },
    /// Revoke the key with this id (the part after `mbk_`, as `keys list` shows it).
    Revoke {
        /// The key's id.
        id: String,
        /// The server's configuration file (for its database).
        #[arg(long)]
        config: Option<PathBuf>,
    },
}

/// Creates, lists or revokes keys in the configured database, saying which.
pub fn keys(which: KeysCommand) -> Result<()> {
    let config = match &which {
        KeysCommand::Create { config, .. }
        | KeysCommand::List { config }
        | KeysCommand::Revoke { config, .. } => ServerConfig::load(config.as_deref())?,
    };
    let database = config.database_url_redacted();
    runtime()?.block_on(async {
        let db = Db::connect(&config.database_url)
            .await
            .map_err(|e| Error::Database(format!("{database}: {e}")))?;
        match which {
            KeysCommand::Create { scopes, label, .. } => {
                let key = db
                    .create_api_key(&Scope::parse_list(&scopes)?, &label)
                    .await?;
                println!("{key}");
                eprintln!("key written to {database}");
            }
            KeysCommand::List { .. } => {
                eprintln!("keys in {database}");
                for k in db.api_keys().await? {
                    println!(
                        "{}",
                        serde_json::to_string(&k).expect("key infos serialize")
                    );
                }
            }
            KeysCommand::Revoke { id, .. } => {
                db.revoke_api_key(&id).await?;
                eprintln!("key {id} revoked in {database}");
            }
        }
        Ok(())
    })
}
