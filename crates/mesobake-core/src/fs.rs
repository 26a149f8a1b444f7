//! File helpers shared by every writer.

use crate::error::{Error, Result};
use std::fs::File;
use std::io::{BufWriter, Read, Write};
use std::path::Path;
use std::sync::OnceLock;
use std::sync::atomic::{AtomicU64, Ordering};

/// Reads a file of `what` (e.g. "OBJ file"), refusing one larger than `max_bytes`: by its
/// length before reading, and by what it yields while reading (a device such as /dev/zero,
/// or a file still growing, reports a length that bounds nothing).
pub fn read_bounded(path: &Path, what: &str, max_bytes: u64) -> Result<Vec<u8>> {
    let too_large = |needed| Error::MemoryLimit {
        what: format!("{what} {}", path.display()),
        needed,
        limit: max_bytes,
    };
    let file = File::open(path).map_err(|e| Error::io(path, e))?;
    let len = file.metadata().map_err(|e| Error::io(path, e))?.len();
    if len > max_bytes {
        return Err(too_large(len));
    }
    let mut bytes = Vec::with_capacity(len as usize);
    file.take(max_bytes.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(|e| Error::io(path, e))?;
    if bytes.len() as u64 > max_bytes {
        return Err(too_large(bytes.len() as u64));
    }
    Ok(bytes)
}

/// A fresh name for a temporary file of `name`, `.NAME.tmpPID-TOKEN-N`: unique per process
/// and per call, so that concurrent writers of one path (two uploads of the same blob) each
/// rename their own complete file, and telling a cleanup which process wrote it: its id, and
/// a token of this run of it ([`process_token`]), which a later process given the same id
/// (a restarted container's) does not share.
pub fn temp_name(name: &str) -> String {
    static CALLS: AtomicU64 = AtomicU64::new(0);
    format!(
        ".{name}.tmp{}-{}-{}",
        std::process::id(),
        process_token(),
        CALLS.fetch_add(1, Ordering::Relaxed)
    )
}

/// A random token of this run of the process (12 hex digits), the same for every call.
pub fn process_token() -> &'static str {
    static TOKEN: OnceLock<String> = OnceLock::new();
    TOKEN.get_or_init(|| uuid::Uuid::new_v4().simple().to_string()[..12].to_string())
}

/// Writes `bytes` to `path` atomically (see [`write_atomic_with`]).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic_with(path, |w| w.write_all(bytes))
}

/// Streams `fill` into a temporary file in the target's directory, syncs it and renames it
/// over `path`, so a crash or an error never leaves a half-written file under that name.
pub fn write_atomic_with(
    path: &Path,
    fill: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
) -> Result<()> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = path
        .file_name()
        .ok_or_else(|| Error::InvalidParameter(format!("{} is not a file path", path.display())))?;
    let tmp = dir.join(temp_name(&name.to_string_lossy()));
    let result = (|| {
        let mut w = BufWriter::with_capacity(1 << 20, File::create(&tmp)?);
        fill(&mut w)?;
        let f = w.into_inner().map_err(|e| e.into_error())?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)?;
        // Make the rename itself durable (best effort: not every platform syncs directories).
        if let Ok(d) = File::open(dir) {
            let _ = d.sync_all();
        }
        Ok(())
    })();
    result.map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        Error::io(path, e)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// /dev/zero reports a length of 0 and never ends: the limit stops the read.
    #[test]
    fn a_device_without_end_is_read_only_up_to_the_limit() {
        let zero = Path::new("/dev/zero");
        if !zero.exists() {
            return;
        }
        match read_bounded(zero, "scene", 4096) {
            Err(Error::MemoryLimit { needed, limit, .. }) => {
                assert_eq!((needed, limit), (4097, 4096));
            }
            other => panic!("{other:?}"),
        }
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("f");
        std::fs::write(&file, [7u8; 4096]).unwrap();
        assert_eq!(read_bounded(&file, "f", 4096).unwrap(), [7u8; 4096]);
        assert!(read_bounded(&file, "f", 4095).is_err());
    }
}
