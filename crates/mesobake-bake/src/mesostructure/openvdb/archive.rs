//! An OpenVDB file's structure: its header, its grids' descriptors, and each grid's
//! compression, metadata and transform — everything but the voxels, read without touching
//! them (OpenVDB's `Archive::readHeader`, `GridDescriptor::read`, `MetaMap::readMeta` and
//! `Transform::read`, file versions 222 to 225).

/// The first eight bytes of every OpenVDB file.
pub const MAGIC: [u8; 8] = [0x20, 0x42, 0x44, 0x56, 0, 0, 0, 0];

/// Oldest file version read: node-mask compression (OpenVDB 2.0, 2013).
const OLDEST_VERSION: u32 = 222;
/// Newest file version read: half grids (OpenVDB 13).
const NEWEST_VERSION: u32 = 225;

/// A bounds-checked little-endian reader over a file's bytes; every read past the end is an
/// error naming what was being read.
#[derive(Clone)]
pub struct Cursor<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Cursor<'a> {
    /// A reader at byte `at` of `bytes`.
    pub fn new(bytes: &'a [u8], at: usize) -> Cursor<'a> {
        Cursor { bytes, at }
    }

    /// The next `n` bytes.
    pub fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], String> {
        let end = self
            .at
            .checked_add(n)
            .filter(|&end| end <= self.bytes.len());
        let end = end.ok_or_else(|| {
            format!(
                "the file ends in {what} (byte {}, {n} bytes wanted, {} left)",
                self.at,
                self.bytes.len().saturating_sub(self.at)
            )
        })?;
        let slice = &self.bytes[self.at..end];
        self.at = end;
        Ok(slice)
    }

    /// The next `N` bytes.
    pub fn array<const N: usize>(&mut self, what: &str) -> Result<[u8; N], String> {
        let mut out = [0; N];
        out.copy_from_slice(self.take(N, what)?);
        Ok(out)
    }

    /// A little-endian u32.
    pub fn u32(&mut self, what: &str) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.array(what)?))
    }

    /// A little-endian i32.
    pub fn i32(&mut self, what: &str) -> Result<i32, String> {
        Ok(i32::from_le_bytes(self.array(what)?))
    }

    /// A little-endian i64.
    pub fn i64(&mut self, what: &str) -> Result<i64, String> {
        Ok(i64::from_le_bytes(self.array(what)?))
    }

    /// A little-endian f64.
    pub fn f64(&mut self, what: &str) -> Result<f64, String> {
        Ok(f64::from_le_bytes(self.array(what)?))
    }

    /// A u32 length and that many bytes of text (lossily decoded).
    pub fn string(&mut self, what: &str) -> Result<String, String> {
        let n = self.u32(what)? as usize;
        Ok(String::from_utf8_lossy(self.take(n, what)?).into_owned())
    }
}

/// What a grid's values are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ValueType {
    /// `float`.
    Float,
    /// `double`.
    Double,
    /// `vec3s`: three floats.
    Vec3s,
    /// `vec3d`: three doubles.
    Vec3d,
}

impl ValueType {
    /// Components per value.
    pub fn components(self) -> usize {
        match self {
            ValueType::Float | ValueType::Double => 1,
            ValueType::Vec3s | ValueType::Vec3d => 3,
        }
    }

    /// Bytes per component as stored (2 when saved as half floats).
    pub fn component_bytes(self, half: bool) -> usize {
        match (half, self) {
            (true, _) => 2,
            (false, ValueType::Float | ValueType::Vec3s) => 4,
            (false, ValueType::Double | ValueType::Vec3d) => 8,
        }
    }
}

/// A grid's index-to-world map: voxel (x, y, z)'s centre is at `voxel_size·(x, y, z) +
/// translation`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform {
    /// The edge of a voxel in world units.
    pub voxel_size: f64,
    /// Where index (0, 0, 0) lies.
    pub translation: [f64; 3],
}

/// One grid of a file, as its descriptor and header say.
#[derive(Clone, Debug)]
pub struct GridInfo {
    /// The grid's name.
    pub name: String,
    /// The value type, when mesobake reads it; else the file's type name.
    pub value_type: Result<ValueType, String>,
    /// Whether the values are stored as half floats.
    pub half: bool,
    /// The grid class (`level set`, `fog volume`, `staggered`, `unknown`).
    pub class: String,
    /// The index-space bounding box of the active voxels the writer recorded
    /// (`file_bbox_min`, `file_bbox_max`), if it did.
    pub bbox: Option<([i32; 3], [i32; 3])>,
    /// The index-to-world map, or why it is not read.
    pub transform: Result<Transform, String>,
    /// The compression flags (`COMPRESS_ZIP` 1, `COMPRESS_ACTIVE_MASK` 2, `COMPRESS_BLOSC` 4).
    pub compression: u32,
    /// The grid whose tree this one shares, when it is an instance.
    pub instance_of: Option<String>,
    /// Where the grid's tree topology starts.
    pub tree_at: usize,
}

/// An OpenVDB file's grids, read from its bytes without their voxels.
#[derive(Clone, Debug)]
pub struct Archive {
    /// The file format version.
    pub version: u32,
    /// The grids, in file order.
    pub grids: Vec<GridInfo>,
}

impl Archive {
    /// Reads the header and every grid's descriptor, metadata and transform.
    pub fn read(bytes: &[u8]) -> Result<Archive, String> {
        let mut c = Cursor::new(bytes, 0);
        if c.array::<8>("the magic number").ok() != Some(MAGIC) {
            return Err("not an OpenVDB file (no magic number)".into());
        }
        let version = c.u32("the file version")?;
        if !(OLDEST_VERSION..=NEWEST_VERSION).contains(&version) {
            return Err(format!(
                "file format version {version}: mesobake reads versions {OLDEST_VERSION} to \
                 {NEWEST_VERSION} (OpenVDB 2.0 to 13)"
            ));
        }
        c.take(8, "the library version")?;
        let offsets = c.array::<1>("the grid-offsets flag")?[0] != 0;
        if !offsets {
            return Err("the file has no grid offsets (a stream, not a file)".into());
        }
        c.take(36, "the file's UUID")?;
        read_metadata(&mut c, "the file's metadata")?;
        let count = c.i32("the grid count")?;
        let count = usize::try_from(count).map_err(|_| format!("{count} grids"))?;
        let mut grids = Vec::new();
        for g in 0..count {
            let what = format!("grid descriptor {g}");
            let unique = c.string(&what)?;
            let name = unique.split('\x1e').next().unwrap_or_default().to_string();
            let type_name = c.string(&what)?;
            let parent = c.string(&what)?;
            let grid_at = c.i64(&what)?;
            c.take(8, &what)?;
            // The next descriptor follows this grid's end.
            let end = c.i64(&what)?;
            c = match usize::try_from(end) {
                Ok(end) if end >= c.at && end <= bytes.len() => Cursor::new(bytes, end),
                _ => {
                    return Err(format!(
                        "grid {name:?} ends at byte {end}, outside the file"
                    ));
                }
            };
            let (base, half) = match type_name.strip_suffix("_HalfFloat") {
                Some(base) => (base, true),
                None => (type_name.as_str(), false),
            };
            let value_type = match base {
                "Tree_float_5_4_3" => Ok(ValueType::Float),
                "Tree_double_5_4_3" => Ok(ValueType::Double),
                "Tree_vec3s_5_4_3" => Ok(ValueType::Vec3s),
                "Tree_vec3d_5_4_3" => Ok(ValueType::Vec3d),
                other => Err(other.to_string()),
            };
            let grid_at = usize::try_from(grid_at)
                .ok()
                .filter(|&at| at < bytes.len())
                .ok_or_else(|| {
                    format!("grid {name:?} starts at byte {grid_at}, outside the file")
                })?;
            let mut g = Cursor::new(bytes, grid_at);
            let what = format!("grid {name:?}'s header");
            let compression = g.u32(&what)?;
            let metadata = read_metadata(&mut g, &what)?;
            let transform = read_transform(&mut g, &what)?;
            grids.push(GridInfo {
                name,
                value_type,
                half,
                class: metadata.class.unwrap_or_else(|| "unknown".into()),
                bbox: metadata.bbox_min.zip(metadata.bbox_max),
                transform,
                compression,
                instance_of: (!parent.is_empty()).then_some(parent),
                tree_at: g.at,
            });
        }
        Ok(Archive { version, grids })
    }

    /// The grid named `name`.
    pub fn grid(&self, name: &str) -> Option<&GridInfo> {
        self.grids.iter().find(|g| g.name == name)
    }
}

/// The metadata mesobake uses.
#[derive(Default)]
struct Metadata {
    class: Option<String>,
    bbox_min: Option<[i32; 3]>,
    bbox_max: Option<[i32; 3]>,
}

/// Reads a metadata map (a count, then name, type name, byte count and bytes per entry),
/// keeping what [`Metadata`] holds.
fn read_metadata(c: &mut Cursor, what: &str) -> Result<Metadata, String> {
    let mut meta = Metadata::default();
    for _ in 0..c.u32(what)? {
        let name = c.string(what)?;
        let type_name = c.string(what)?;
        let n = c.u32(what)? as usize;
        let value = c.take(n, what)?;
        let vec3i = || -> Option<[i32; 3]> {
            let v: &[u8; 12] = value.try_into().ok()?;
            Some(std::array::from_fn(|i| {
                i32::from_le_bytes([v[4 * i], v[4 * i + 1], v[4 * i + 2], v[4 * i + 3]])
            }))
        };
        match (name.as_str(), type_name.as_str()) {
            ("class", "string") => meta.class = Some(String::from_utf8_lossy(value).into()),
            ("file_bbox_min", "vec3i") => meta.bbox_min = vec3i(),
            ("file_bbox_max", "vec3i") => meta.bbox_max = vec3i(),
            _ => {}
        }
    }
    Ok(meta)
}

/// Reads a transform: the map's type name, then its fields. Maps that only scale (uniformly)
/// and translate are read; others are named in the error.
fn read_transform(c: &mut Cursor, what: &str) -> Result<Result<Transform, String>, String> {
    let map = c.string(what)?;
    let vec3 = |c: &mut Cursor| -> Result<[f64; 3], String> {
        Ok([c.f64(what)?, c.f64(what)?, c.f64(what)?])
    };
    let (translation, scale) = match map.as_str() {
        "TranslationMap" => (vec3(c)?, [1.0; 3]),
        "UniformScaleMap" | "ScaleMap" => ([0.0; 3], vec3(c)?),
        "UniformScaleTranslateMap" | "ScaleTranslateMap" => {
            let t = vec3(c)?;
            (t, vec3(c)?)
        }
        other => {
            return Ok(Err(format!(
                "its transform is a {other}; mesobake reads grids whose transform only \
                 scales and translates"
            )));
        }
    };
    if map != "TranslationMap" {
        // The voxel size, the inverse scale and its square and half: derived, skipped.
        c.take(4 * 24, what)?;
    }
    let voxel_size = scale[0];
    let uniform = scale
        .iter()
        .all(|s| (s - voxel_size).abs() <= 1e-9 * voxel_size.abs());
    if !(voxel_size.is_finite() && voxel_size > 0.0 && uniform)
        || translation.iter().any(|t| !t.is_finite())
    {
        return Ok(Err(format!(
            "its voxels are {scale:?} (translation {translation:?}): mesobake reads cubic \
             voxels of a finite positive size"
        )));
    }
    Ok(Ok(Transform {
        voxel_size,
        translation,
    }))
}
