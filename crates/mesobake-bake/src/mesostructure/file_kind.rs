//! What an input file holds, told by its content: magic numbers first, then whether it is
//! JSON or OBJ text. A file's extension is only a hint, used in messages when it disagrees.

use mesobake_core::error::{Error, Result};
use std::io::Read;
use std::path::Path;

/// How much of a file [`FileKind::of_file`] reads to tell its kind.
const HEAD_BYTES: u64 = 64 << 10;

/// The kinds of file a user may hand mesobake.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FileKind {
    /// A `.mbvol` voxel volume.
    Volume,
    /// A PNG image (a height field, when grayscale).
    Png,
    /// OBJ text.
    Obj,
    /// A `.mbpkg` package.
    Package,
    /// An OpenEXR image.
    Exr,
    /// An OpenVDB file.
    OpenVdb,
    /// A NumPy `.npy` array.
    Npy,
    /// JSON text (a scene, a job).
    Json,
    /// Text that is not OBJ.
    Text,
    /// Binary data of no kind mesobake reads.
    Binary,
    /// Nothing at all.
    Empty,
}

/// OBJ's statement keywords (geometry, grouping, materials, free-form surfaces).
const OBJ_KEYWORDS: [&str; 31] = [
    "v", "vt", "vn", "vp", "f", "l", "p", "o", "g", "s", "mg", "mtllib", "usemtl", "cstype", "deg",
    "bmat", "step", "curv", "curv2", "surf", "parm", "trim", "hole", "scrv", "sp", "end", "con",
    "lod", "ctech", "stech", "call",
];

impl FileKind {
    /// The kind of a file whose first bytes are `head` (any prefix of the file; text kinds
    /// are judged on the lines it holds).
    pub fn detect(head: &[u8]) -> FileKind {
        let magics: [(&[u8], FileKind); 6] = [
            (crate::mesostructure::volume_format::MAGIC, FileKind::Volume),
            (
                &crate::mesostructure::height_field::PNG_MAGIC,
                FileKind::Png,
            ),
            (&mesobake_package::container::MAGIC, FileKind::Package),
            (&[0x76, 0x2f, 0x31, 0x01], FileKind::Exr),
            (b"\x93NUMPY", FileKind::Npy),
            (
                &crate::mesostructure::openvdb::archive::MAGIC,
                FileKind::OpenVdb,
            ),
        ];
        if head.is_empty() {
            return FileKind::Empty;
        }
        if let Some((_, kind)) = magics.iter().find(|(magic, _)| head.starts_with(magic)) {
            return *kind;
        }
        let text = match std::str::from_utf8(head) {
            Ok(text) => text,
            // A character cut by the end of the head is still text.
            Err(e) if e.error_len().is_none() => {
                std::str::from_utf8(&head[..e.valid_up_to()]).unwrap_or_default()
            }
            Err(_) => return FileKind::Binary,
        };
        if text.contains('\0') {
            return FileKind::Binary;
        }
        if text.trim_start().starts_with(['{', '[']) {
            return FileKind::Json;
        }
        // Every statement line (the last one may be cut) starts with an OBJ keyword.
        let cut = head.len() as u64 >= HEAD_BYTES;
        let lines: Vec<&str> = text.lines().collect();
        let whole = if cut {
            lines.len().saturating_sub(1)
        } else {
            lines.len()
        };
        let is_obj = lines[..whole].iter().all(|line| {
            let line = line.trim();
            line.is_empty()
                || line.starts_with('#')
                || line.starts_with('\\')
                || line
                    .split_whitespace()
                    .next()
                    .is_some_and(|word| OBJ_KEYWORDS.contains(&word))
        });
        if is_obj {
            FileKind::Obj
        } else {
            FileKind::Text
        }
    }

    /// The kind of the file at `path`, from its first 64 KiB.
    pub fn of_file(path: &Path) -> Result<FileKind> {
        let mut head = Vec::new();
        std::fs::File::open(path)
            .and_then(|f| f.take(HEAD_BYTES).read_to_end(&mut head))
            .map_err(|e| Error::io(path, e))?;
        Ok(FileKind::detect(&head))
    }

    /// The kind a file's extension suggests, if it suggests one.
    pub fn of_extension(path: &Path) -> Option<FileKind> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        Some(match ext.as_str() {
            "mbvol" => FileKind::Volume,
            "png" => FileKind::Png,
            "obj" => FileKind::Obj,
            "mbpkg" => FileKind::Package,
            "exr" => FileKind::Exr,
            "npy" => FileKind::Npy,
            "vdb" => FileKind::OpenVdb,
            "json" => FileKind::Json,
            "txt" | "md" | "csv" => FileKind::Text,
            _ => return None,
        })
    }

    /// What the kind is, in words: "a .mbvol volume", "JSON text", …
    pub fn describe(self) -> &'static str {
        match self {
            FileKind::Volume => "a .mbvol volume",
            FileKind::Png => "a PNG image",
            FileKind::Obj => "OBJ text",
            FileKind::Package => "a .mbpkg package",
            FileKind::Exr => "an OpenEXR image",
            FileKind::OpenVdb => "an OpenVDB file (`mesobake import` makes a volume of it)",
            FileKind::Npy => "a NumPy .npy array",
            FileKind::Json => "JSON text",
            FileKind::Text => "text that is not OBJ",
            FileKind::Binary => "binary data of no kind mesobake reads",
            FileKind::Empty => "an empty file",
        }
    }

    /// "PATH is KIND", with what its name suggests when that differs: for messages.
    pub fn describe_file(self, path: &Path) -> String {
        match FileKind::of_extension(path) {
            Some(named) if named != self => format!(
                "{} is {} (though its name suggests {})",
                path.display(),
                self.describe(),
                named.describe()
            ),
            _ => format!("{} is {}", path.display(), self.describe()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kinds_are_told_by_content() {
        let cases: [(&[u8], FileKind); 13] = [
            (b"MBVOL\0\r\n\x01\x00", FileKind::Volume),
            (b"\x89PNG\r\n\x1a\n....", FileKind::Png),
            (b"\x89MBPKG\r\n....", FileKind::Package),
            (b"\x76\x2f\x31\x01\x02", FileKind::Exr),
            (b"\x93NUMPY\x01\x00", FileKind::Npy),
            (b"\x20BDV\0\0\0\0\xe0\0\0\0", FileKind::OpenVdb),
            (b"  {\"scene\": 1}", FileKind::Json),
            (
                b"# a tile\nv 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2 3\n",
                FileKind::Obj,
            ),
            (
                b"o tile\r\ng part\nusemtl m\nvt 0 0\nvn 0 0 1\nf 1/1/1 2/1/1 3/1/1",
                FileKind::Obj,
            ),
            (b"hello, this is not a mesh\n", FileKind::Text),
            (b"v 0 0 0\nnot obj\n", FileKind::Text),
            (b"\x00\x01\x02\xff", FileKind::Binary),
            (b"", FileKind::Empty),
        ];
        for (head, kind) in cases {
            assert_eq!(
                FileKind::detect(head),
                kind,
                "{:?}",
                String::from_utf8_lossy(head)
            );
        }
        // A head that ends inside a line or a character is judged on what it holds.
        let mut long = "v 0 0 0\n".repeat(9000).into_bytes();
        long.truncate(HEAD_BYTES as usize - 1);
        long.push(0xc3);
        assert_eq!(FileKind::detect(&long), FileKind::Obj);
    }

    #[test]
    fn messages_say_what_the_name_suggests_when_it_differs() {
        let json = FileKind::Json.describe_file(Path::new("fake.mbvol"));
        assert_eq!(
            json,
            "fake.mbvol is JSON text (though its name suggests a .mbvol volume)"
        );
        assert_eq!(
            FileKind::Obj.describe_file(Path::new("t.obj")),
            "t.obj is OBJ text"
        );
    }
}
