//! The content-addressed blob store: uploads, packages and previews, each under the BLAKE3
//! hash of its bytes (lowercase hex) at `DATA_DIR/blobs/<first two hex>/<hash>`.
//!
//! Writes go to a temporary file in the same directory, are synced and renamed into place
//! (`fsutil::write_atomic`), so a crash never leaves a half-written blob under a valid key;
//! writing a key that exists is a no-op (same key, same bytes). Keys are validated before
//! they become paths, so no name from a request can reach outside the store.

use crate::error::{Error, Result};
use crate::fsutil::write_atomic;
use std::path::{Path, PathBuf};

/// A local blob store.
#[derive(Clone, Debug)]
pub struct BlobStore {
    root: PathBuf,
}

/// Whether `key` is a blob key: 64 lowercase hexadecimal digits.
pub fn is_key(key: &str) -> bool {
    key.len() == 64 && key.bytes().all(|b| matches!(b, b'0'..=b'9' | b'a'..=b'f'))
}

/// The key of `bytes`.
pub fn key_of(bytes: &[u8]) -> String {
    blake3::hash(bytes).to_hex().to_string()
}

impl BlobStore {
    /// Opens (creating if needed) the store under `data_dir`.
    pub fn open(data_dir: &Path) -> Result<BlobStore> {
        let root = data_dir.join("blobs");
        std::fs::create_dir_all(&root).map_err(|e| Error::io(&root, e))?;
        Ok(BlobStore { root })
    }

    /// The path of blob `key`, or an error for a string that is not a key.
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
            Ok(bytes) if key_of(&bytes) == key => Ok(Some(bytes)),
            Ok(_) => Err(Error::Io {
                path,
                source: std::io::Error::new(
                    std::io::ErrorKind::InvalidData,
                    "blob content does not match its key (corrupted store)",
                ),
            }),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
            Err(e) => Err(Error::io(path, e)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blobs_round_trip_deduplicate_and_reject_non_keys() {
        let dir = tempfile::tempdir().unwrap();
        let store = BlobStore::open(dir.path()).unwrap();
        let key = store.put(b"chain mail").unwrap();
        assert_eq!(key, key_of(b"chain mail"));
        assert_eq!(store.put(b"chain mail").unwrap(), key);
        assert_eq!(store.get(&key).unwrap().unwrap(), b"chain mail");
        assert!(store.get(&key_of(b"absent")).unwrap().is_none());
        for bad in ["../../etc/passwd", "", &key.to_uppercase(), &key[..63]] {
            assert!(store.path(bad).is_err(), "{bad}");
        }
        // A blob whose bytes no longer match its key is reported, not served.
        std::fs::write(store.path(&key).unwrap(), b"chain mall").unwrap();
        assert!(store.get(&key).is_err());
    }
}
