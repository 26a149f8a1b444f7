//! The content-addressed blob store: uploads, packages and previews, each under the BLAKE3
//! hash of its bytes (lowercase hex).
//!
//! Two backends, chosen by `blob_url` in the configuration:
//! - **local** (the default, `blob_url = ""`): files at `DATA_DIR/blobs/<first two hex>/<hash>`.
//!   Writes go to a temporary file in the same directory, are synced and renamed into place
//!   (`mesobake_core::fs::write_atomic`), so a crash never leaves a half-written blob under a valid key.
//! - **S3** (`blob_url = "s3://BUCKET[/PREFIX]"`, through the `object_store` crate): objects at
//!   `PREFIX/<hash>`, shared by every server and worker on every machine. An S3 PUT is atomic
//!   (the object appears whole or not at all). The local directory becomes a read-through
//!   cache of the same layout, filled atomically, so the bake reads assets as files.
//!
//! Writing a key that exists is a no-op (same key, same bytes). Every read is checked against
//! its key. Keys are validated before they become paths, so no name from a request can reach
//! outside the store.

use mesobake_core::error::{Error, Result};
use mesobake_core::fs::{process_token, temp_name, write_atomic};
use object_store::aws::{AmazonS3Builder, AmazonS3ConfigKey};
use object_store::path::Path as ObjectPath;
use object_store::prefix::PrefixStore;
use object_store::{ObjectStore, ObjectStoreExt, PutPayload};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A blob store: a local directory, or an S3 bucket with a local cache.
#[derive(Clone, Debug)]
pub struct BlobStore {
    /// The local store, or the cache of the remote one.
    root: PathBuf,
    remote: Option<Arc<Remote>>,
}

/// Whether `key` is a blob key: 64 lowercase hexadecimal digits.
pub fn is_key(key: &str) -> bool {
    key.len() == 64 && key.bytes().all(|b| matches!(b, b'0'..=b'9' | b'a'..=b'f'))
}

/// The key of `bytes`.
pub fn key_of(bytes: &[u8]) -> String {
    blake3::hash(bytes).to_hex().to_string()
}

fn corrupted(path: PathBuf) -> Error {
    Error::Io {
        path,
        source: std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            "blob content does not match its key (corrupted store)",
        ),
    }
}

impl BlobStore {
    /// Opens (creating if needed) the store under `data_dir`: local when `blob_url` is empty,
    /// else the S3 bucket it names, configured by `options` (object_store's S3 keys such as
    /// `endpoint`, `region`, `access_key_id`, `allow_http`) over the standard `AWS_*`
    /// environment variables.
    pub fn open(
        data_dir: &Path,
        blob_url: &str,
        options: &BTreeMap<String, String>,
    ) -> Result<BlobStore> {
        let root =
            std::path::absolute(data_dir.join("blobs")).map_err(|e| Error::io(data_dir, e))?;
        std::fs::create_dir_all(&root).map_err(|e| Error::io(&root, e))?;
        let remote = match blob_url {
            "" if options.is_empty() => None,
            "" => {
                return Err(Error::InvalidParameter(
                    "blob_options are set but blob_url is empty (the local store takes none)"
                        .into(),
                ));
            }
            url => Some(Arc::new(Remote::open(url, options)?)),
        };
        Ok(BlobStore { root, remote })
    }

    /// The local path of blob `key` (in the cache, for S3), or an error for a string that is
    /// not a key.
    pub fn path(&self, key: &str) -> Result<PathBuf> {
        if !is_key(key) {
            return Err(Error::InvalidParameter(format!(
                "{key:?} is not a blob digest (64 lowercase hex digits)"
            )));
        }
        Ok(self.root.join(&key[..2]).join(key))
    }

    /// Stores `bytes`, returning their key; a blob already stored is left as it is.
    pub fn put(&self, bytes: &[u8]) -> Result<String> {
        let key = key_of(bytes);
        let path = self.path(&key)?;
        if let Some(remote) = &self.remote {
            remote.put(&key, bytes)?;
        }
        if !path.exists() {
            let dir = path.parent().expect("blob paths have a parent");
            std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
            write_atomic(&path, bytes)?;
        }
        Ok(key)
    }

    /// The bytes of blob `key`, checked against the key (`None` when absent).
    pub fn get(&self, key: &str) -> Result<Option<Vec<u8>>> {
        let path = self.path(key)?;
        match std::fs::read(&path) {
            Ok(bytes) if key_of(&bytes) == key => return Ok(Some(bytes)),
            // A corrupted cache entry is fetched again; a corrupted local store is an error.
            Ok(_) if self.remote.is_none() => return Err(corrupted(path)),
            Ok(_) => {}
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(Error::io(path, e)),
        }
        let Some(remote) = &self.remote else {
            return Ok(None);
        };
        let Some(bytes) = remote.get(key)? else {
            return Ok(None);
        };
        if key_of(&bytes) != key {
            return Err(corrupted(remote.location(key)));
        }
        let dir = path.parent().expect("blob paths have a parent");
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        write_atomic(&path, &bytes)?;
        Ok(Some(bytes))
    }

    /// Stores the complete file `tmp` (from [`BlobStore::temp_path`]) as blob `key`, which
    /// the caller computed from its bytes, moving it into place rather than copying it.
    pub fn put_file(&self, tmp: &Path, key: &str) -> Result<()> {
        let path = self.path(key)?;
        if let Some(remote) = &self.remote {
            let bytes = std::fs::read(tmp).map_err(|e| Error::io(tmp, e))?;
            remote.put(key, &bytes)?;
        }
        if path.exists() {
            std::fs::remove_file(tmp).map_err(|e| Error::io(tmp, e))?;
            return Ok(());
        }
        let dir = path.parent().expect("blob paths have a parent");
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        std::fs::File::open(tmp)
            .and_then(|f| f.sync_all())
            .and_then(|()| std::fs::rename(tmp, &path))
            .map_err(|e| Error::io(&path, e))
    }

    /// A fresh path for a temporary file inside the store (same file system as the blobs,
    /// so that [`BlobStore::put_file`] renames it; named like [`write_atomic`]'s files so
    /// that [`BlobStore::remove_leftovers`] finds it after a crash).
    pub fn temp_path(&self) -> Result<PathBuf> {
        let dir = self.root.join("tmp");
        std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
        Ok(dir.join(temp_name("upload")))
    }

    /// Removes blob `key` (a cached preview being evicted); absent blobs are no error.
    pub fn remove(&self, key: &str) -> Result<()> {
        let path = self.path(key)?;
        if let Some(remote) = &self.remote {
            remote.delete(key)?;
        }
        match std::fs::remove_file(&path) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(Error::io(path, e)),
            _ => Ok(()),
        }
    }

    /// Writes a fresh probe file, reads it back and removes it (and a probe object in the
    /// bucket, for S3): whether the store takes writes now.
    pub fn probe(&self) -> Result<()> {
        let nonce = uuid::Uuid::new_v4().simple().to_string();
        let path = self.root.join(format!(".probe-{nonce}"));
        write_atomic(&path, nonce.as_bytes())?;
        let back = std::fs::read(&path).map_err(|e| Error::io(&path, e));
        std::fs::remove_file(&path).map_err(|e| Error::io(&path, e))?;
        if back? != nonce.as_bytes() {
            return Err(corrupted(path));
        }
        if let Some(remote) = &self.remote {
            remote.probe(&nonce)?;
        }
        Ok(())
    }

    /// Removes temporary files that a killed process left in the store (named
    /// `.NAME.tmpPID-TOKEN-N`, [`temp_name`]; older ones `.NAME.tmpPID-N`): those of
    /// processes that no longer run on this host — an id that no process has, or this
    /// process's id with another run's token (a restarted container reuses its ids) —
    /// untouched for [`LEFTOVER_AGE`], and any untouched for [`STALE_AGE`] (a process on
    /// another machine sharing the directory). Returns how many were removed.
    pub fn remove_leftovers(&self) -> Result<usize> {
        let mut removed = 0;
        let dirs = std::fs::read_dir(&self.root).map_err(|e| Error::io(&self.root, e))?;
        for dir in dirs.flatten() {
            if !dir.file_type().is_ok_and(|t| t.is_dir()) {
                continue;
            }
            let Ok(files) = std::fs::read_dir(dir.path()) else {
                continue;
            };
            for file in files.flatten() {
                let name = file.file_name().to_string_lossy().into_owned();
                let Some((pid, token)) = leftover_writer(&name) else {
                    continue;
                };
                let age = file
                    .metadata()
                    .and_then(|m| m.modified())
                    .ok()
                    .and_then(|t| t.elapsed().ok())
                    .unwrap_or_default();
                let dead = if pid == std::process::id() {
                    token.is_some_and(|t| t != process_token())
                } else {
                    !process_runs(pid)
                };
                if (dead && age >= LEFTOVER_AGE) || age >= STALE_AGE {
                    match std::fs::remove_file(file.path()) {
                        Ok(()) => removed += 1,
                        Err(e) => tracing::warn!("{}: {e}", file.path().display()),
                    }
                }
            }
        }
        Ok(removed)
    }

    /// `message` with the store's local paths hidden, for answers that must not reveal the
    /// server's directories: a blob's path becomes its key, any other path in the store
    /// `blob store/…`.
    pub fn scrub(&self, message: &str) -> String {
        let root = self.root.display().to_string();
        let mut out = String::with_capacity(message.len());
        let mut rest = message;
        while let Some(at) = rest.find(&root) {
            out += &rest[..at];
            rest = &rest[at + root.len()..];
            // "/ab/KEY": the blob's key alone.
            let blob = rest
                .get(4..68)
                .filter(|key| is_key(key) && rest.get(..4) == Some(&format!("/{}/", &key[..2])));
            match blob {
                Some(key) => {
                    out += key;
                    rest = &rest[68..];
                }
                None => out += "blob store",
            }
        }
        out + rest
    }

    /// The local file of blob `key` (fetched into the cache first, for S3), or `None` when
    /// no such blob exists.
    pub fn file(&self, key: &str) -> Result<Option<PathBuf>> {
        let path = self.path(key)?;
        if path.is_file() {
            return Ok(Some(path));
        }
        if self.remote.is_none() {
            return Ok(None);
        }
        Ok(self.get(key)?.map(|_| path))
    }
}

/// How long a dead process's temporary file is left alone before it is removed.
pub const LEFTOVER_AGE: std::time::Duration = std::time::Duration::from_secs(60);
/// How long any temporary file is left alone before it is taken for a leftover.
pub const STALE_AGE: std::time::Duration = std::time::Duration::from_secs(3600);

/// The writer of a temporary file, from its name ([`temp_name`]'s `.NAME.tmpPID-TOKEN-N`,
/// or the older `.NAME.tmpPID-N`): its process id and run token, if the name is one.
fn leftover_writer(name: &str) -> Option<(u32, Option<&str>)> {
    let (_, tail) = name.strip_prefix('.')?.rsplit_once(".tmp")?;
    let mut parts = tail.split('-');
    let pid = parts.next()?.parse().ok()?;
    match (parts.next()?, parts.next(), parts.next()) {
        (token, Some(_), None) => Some((pid, Some(token))),
        (_, None, _) => Some((pid, None)),
        _ => None,
    }
}

/// Whether process `pid` runs on this host (always "yes" where that cannot be told).
fn process_runs(pid: u32) -> bool {
    if cfg!(target_os = "linux") {
        Path::new(&format!("/proc/{pid}")).exists()
    } else {
        true
    }
}

/// An S3 bucket, driven by its own small tokio runtime so that the store's synchronous
/// methods work from any thread (bake threads, blocking tasks, tests).
#[derive(Debug)]
struct Remote {
    /// The bucket, under the prefix.
    store: Arc<dyn ObjectStore>,
    /// `s3://bucket/prefix`, for messages.
    url: String,
    runtime: OwnedRuntime,
}

impl Remote {
    fn open(url: &str, options: &BTreeMap<String, String>) -> Result<Remote> {
        let bad = |why: String| Error::InvalidParameter(format!("blob_url {url:?}: {why}"));
        let rest = url
            .strip_prefix("s3://")
            .ok_or_else(|| bad("only s3://BUCKET[/PREFIX] is supported".into()))?;
        let (bucket, prefix) = rest.split_once('/').unwrap_or((rest, ""));
        if bucket.is_empty() {
            return Err(bad("no bucket name".into()));
        }
        let prefix = prefix.trim_matches('/').to_string();
        let mut builder = AmazonS3Builder::from_env().with_bucket_name(bucket);
        for (key, value) in options {
            let config_key: AmazonS3ConfigKey = key.parse().map_err(|_| {
                Error::InvalidParameter(format!("blob_options: unknown S3 option {key:?}"))
            })?;
            builder = builder.with_config(config_key, value);
        }
        let s3 = builder.build().map_err(|e| bad(e.to_string()))?;
        let store: Arc<dyn ObjectStore> = if prefix.is_empty() {
            Arc::new(s3)
        } else {
            Arc::new(PrefixStore::new(s3, prefix.as_str()))
        };
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .thread_name("mesobake-s3")
            .enable_all()
            .build()
            .map_err(|e| Error::io("tokio runtime", e))?;
        Ok(Remote {
            store,
            url: format!("s3://{bucket}/{prefix}"),
            runtime: OwnedRuntime(Some(runtime)),
        })
    }

    /// Where `key` lives, for messages.
    fn location(&self, key: &str) -> PathBuf {
        PathBuf::from(format!("{}/{key}", self.url.trim_end_matches('/')))
    }

    /// Runs `task` on the store's runtime and waits for it, from any thread.
    fn run<T: Send + 'static>(&self, task: impl Future<Output = T> + Send + 'static) -> Result<T> {
        let runtime = self
            .runtime
            .0
            .as_ref()
            .expect("the runtime lives as long as the store");
        let (send, receive) = std::sync::mpsc::sync_channel(1);
        runtime.spawn(async move {
            let _ = send.send(task.await);
        });
        receive
            .recv()
            .map_err(|_| Error::io(&self.url, std::io::Error::other("S3 task was dropped")))
    }

    fn failed(&self, key: &str, e: object_store::Error) -> Error {
        Error::io(self.location(key), std::io::Error::other(e))
    }

    fn put(&self, key: &str, bytes: &[u8]) -> Result<()> {
        let (store, object) = (self.store.clone(), ObjectPath::from(key));
        let payload = PutPayload::from(bytes.to_vec());
        let result = self.run(async move {
            match store.head(&object).await {
                Ok(_) => Ok(()),
                Err(object_store::Error::NotFound { .. }) => {
                    store.put(&object, payload).await.map(|_| ())
                }
                Err(e) => Err(e),
            }
        })?;
        result.map_err(|e| self.failed(key, e))
    }

    fn delete(&self, key: &str) -> Result<()> {
        let (store, object) = (self.store.clone(), ObjectPath::from(key));
        let result = self.run(async move {
            match store.delete(&object).await {
                Ok(()) | Err(object_store::Error::NotFound { .. }) => Ok(()),
                Err(e) => Err(e),
            }
        })?;
        result.map_err(|e| self.failed(key, e))
    }

    /// Writes and deletes the object `probes/NONCE`.
    fn probe(&self, nonce: &str) -> Result<()> {
        let name = format!("probes/{nonce}");
        let (store, object) = (self.store.clone(), ObjectPath::from(name.as_str()));
        let payload = PutPayload::from(nonce.as_bytes().to_vec());
        let result = self.run(async move {
            store.put(&object, payload).await?;
            store.delete(&object).await
        })?;
        result.map_err(|e| self.failed(&name, e))
    }

    fn get(&self, key: &str) -> Result<Option<Vec<u8>>> {
        let (store, object) = (self.store.clone(), ObjectPath::from(key));
        let result = self.run(async move {
            match store.get(&object).await {
                Ok(found) => found.bytes().await.map(|b| Some(b.to_vec())),
                Err(object_store::Error::NotFound { .. }) => Ok(None),
                Err(e) => Err(e),
            }
        })?;
        result.map_err(|e| self.failed(key, e))
    }
}

/// A runtime that may be dropped anywhere, async contexts included.
#[derive(Debug)]
struct OwnedRuntime(Option<tokio::runtime::Runtime>);

impl Drop for OwnedRuntime {
    fn drop(&mut self) {
        if let Some(runtime) = self.0.take() {
            runtime.shutdown_background();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn local(dir: &Path) -> BlobStore {
        BlobStore::open(dir, "", &BTreeMap::new()).unwrap()
    }

    #[test]
    fn blobs_round_trip_deduplicate_and_reject_non_keys() {
        let dir = tempfile::tempdir().unwrap();
        let store = local(dir.path());
        let key = store.put(b"chain mail").unwrap();
        assert_eq!(key, key_of(b"chain mail"));
        assert_eq!(store.put(b"chain mail").unwrap(), key);
        assert_eq!(store.get(&key).unwrap().unwrap(), b"chain mail");
        assert_eq!(store.file(&key).unwrap(), Some(store.path(&key).unwrap()));
        assert!(store.get(&key_of(b"absent")).unwrap().is_none());
        assert!(store.file(&key_of(b"absent")).unwrap().is_none());
        for bad in ["../../etc/passwd", "", &key.to_uppercase(), &key[..63]] {
            assert!(store.path(bad).is_err(), "{bad}");
        }
        // A blob whose bytes no longer match its key is reported, not served.
        std::fs::write(store.path(&key).unwrap(), b"chain mall").unwrap();
        assert!(store.get(&key).is_err());
    }

    #[test]
    fn leftovers_of_dead_processes_are_removed_and_live_ones_kept() {
        let dir = tempfile::tempdir().unwrap();
        let store = local(dir.path());
        let key = store.put(b"kept").unwrap();
        let shard = store.path(&key).unwrap().parent().unwrap().to_owned();
        let old = std::time::SystemTime::now() - 2 * LEFTOVER_AGE;
        let make = |name: &str, modified: std::time::SystemTime| {
            let path = shard.join(name);
            std::fs::write(&path, b"half a blob").unwrap();
            std::fs::File::options()
                .write(true)
                .open(&path)
                .unwrap()
                .set_modified(modified)
                .unwrap();
            path
        };
        // No process has a pid this large (Linux caps them at 2^22).
        let dead_old = make(&format!(".{key}.tmp{}-0", 1u32 << 30), old);
        let dead_fresh = make(
            &format!(".{key}.tmp{}-1", 1u32 << 30),
            std::time::SystemTime::now(),
        );
        let live_old = make(&format!(".{key}.tmp{}-2", std::process::id()), old);
        // This process's id from an earlier run (a restarted container's): its writer is dead.
        let earlier_run = make(
            &format!(".{key}.tmp{}-0123456789ab-3", std::process::id()),
            old,
        );
        let ours_old = make(&temp_name(&key), old);
        let upload = store.temp_path().unwrap();
        std::fs::write(&upload, b"streaming").unwrap();
        assert_eq!(store.remove_leftovers().unwrap(), 2);
        assert!(!dead_old.exists() && !earlier_run.exists());
        assert!(dead_fresh.exists() && live_old.exists() && ours_old.exists() && upload.exists());
        assert_eq!(store.get(&key).unwrap().unwrap(), b"kept");
    }

    #[test]
    fn probes_leave_nothing_and_scrubbed_messages_keep_only_keys() {
        let dir = tempfile::tempdir().unwrap();
        let store = local(dir.path());
        store.probe().unwrap();
        assert_eq!(std::fs::read_dir(&store.root).unwrap().count(), 0);
        let key = key_of(b"x");
        let message = format!(
            "scene: {} is a 8x8x4 volume; {}: Not a directory",
            store.path(&key).unwrap().display(),
            store.root.join("ab").display()
        );
        assert_eq!(
            store.scrub(&message),
            format!("scene: {key} is a 8x8x4 volume; blob store/ab: Not a directory")
        );
        let tmp = store.temp_path().unwrap();
        std::fs::write(&tmp, b"x").unwrap();
        store.put_file(&tmp, &key).unwrap();
        assert_eq!(store.get(&key).unwrap().unwrap(), b"x");
        assert!(!tmp.exists());
        store.remove(&key).unwrap();
        assert!(store.get(&key).unwrap().is_none());
    }

    #[test]
    fn bad_remote_configurations_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let options = |pairs: &[(&str, &str)]| -> BTreeMap<String, String> {
            pairs
                .iter()
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .collect()
        };
        for (url, opts, expected) in [
            ("gs://bucket", options(&[]), "only s3://"),
            ("s3://", options(&[]), "no bucket"),
            (
                "s3://b",
                options(&[("colour", "blue")]),
                "unknown S3 option \"colour\"",
            ),
            ("", options(&[("region", "eu")]), "blob_url is empty"),
        ] {
            let e = BlobStore::open(dir.path(), url, &opts)
                .unwrap_err()
                .to_string();
            assert!(e.contains(expected), "{url}: {e}");
        }
    }
}
