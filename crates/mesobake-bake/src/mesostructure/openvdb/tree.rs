//! A grid's 5-4-3 tree read from its file: the root's tiles and children, each internal
//! node's tile values and children, and the leaves' voxels (OpenVDB's `readTopology` and
//! `readBuffers` of `RootNode`, `InternalNode` and `LeafNode`, and `readCompressedValues`),
//! every value widened to f32. Each node is charged to a memory budget before it is
//! allocated, so a small file that describes a huge tree is refused, not read.

use super::archive::{Cursor, GridInfo, ValueType};
use super::blosc;
use std::collections::HashMap;
use std::io::Read;

/// Compression flag: zlib.
const COMPRESS_ZIP: u32 = 0x1;
/// Compression flag: only active values are stored.
const COMPRESS_ACTIVE_MASK: u32 = 0x2;
/// Compression flag: Blosc.
const COMPRESS_BLOSC: u32 = 0x4;

/// log2 of the voxels along one edge of a root child (4096 = 2^(5+4+3)).
const ROOT_CHILD_LOG2: u32 = 12;

/// A voxel's value and whether it is active.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Voxel<'t> {
    /// The value's components (one, or three for a vector grid).
    pub value: &'t [f32],
    /// Whether the voxel is active.
    pub active: bool,
}

/// An internal node (32³ children of 128³ voxels, or 16³ of 8³) or a leaf (8³ voxels).
struct Node {
    /// log2 of the children (or voxels) along an edge: 5, 4 or 3.
    log2: u32,
    /// log2 of the voxels along a child's edge: 7, 3 or 0.
    child_log2: u32,
    origin: [i32; 3],
    /// Which entries are children (empty for a leaf).
    child_mask: Vec<u64>,
    /// Which entries are active.
    value_mask: Vec<u64>,
    /// Each entry's value (tiles for an internal node, voxels for a leaf), `components` each.
    values: Vec<f32>,
    /// Entry → index of the child node in the tree.
    children: HashMap<u32, usize>,
}

impl Node {
    /// The entry holding voxel `p`.
    fn entry(&self, p: [i32; 3]) -> u32 {
        let mask = (1 << self.log2) - 1;
        let [x, y, z] = p.map(|c| ((c >> self.child_log2) & mask) as u32);
        (x << (2 * self.log2)) | (y << self.log2) | z
    }

    /// The origin of entry `n`'s child.
    fn child_origin(&self, n: u32) -> [i32; 3] {
        let mask = (1 << self.log2) - 1;
        let local = [n >> (2 * self.log2), n >> self.log2, n].map(|v| (v & mask) as i32);
        std::array::from_fn(|a| self.origin[a] + (local[a] << self.child_log2))
    }
}

fn bit(mask: &[u64], n: u32) -> bool {
    mask[n as usize >> 6] >> (n & 63) & 1 == 1
}

fn ones(mask: &[u64]) -> impl Iterator<Item = u32> + '_ {
    mask.iter().enumerate().flat_map(|(w, &word)| {
        (0..64)
            .filter(move |b| word >> b & 1 == 1)
            .map(move |b| (w * 64 + b) as u32)
    })
}

/// A grid's tree.
pub struct Tree {
    components: usize,
    background: Vec<f32>,
    /// Root tiles by origin: value and whether active.
    tiles: HashMap<[i32; 3], (Vec<f32>, bool)>,
    /// Root children by origin: index into `nodes`.
    roots: HashMap<[i32; 3], usize>,
    nodes: Vec<Node>,
    /// The bytes charged to the budget while reading.
    charged: u64,
}

/// How a grid's values are stored, and what reading may still allocate.
struct Format {
    value_type: ValueType,
    half: bool,
    compression: u32,
    budget: u64,
}

impl Format {
    fn charge(&mut self, bytes: u64, what: &str) -> Result<(), String> {
        self.budget = self
            .budget
            .checked_sub(bytes)
            .ok_or_else(|| format!("{what} would take the grid's tree over the memory limit"))?;
        Ok(())
    }

    /// Reads `count` values stored at full precision (root tiles, inactive values).
    fn full_values(&self, c: &mut Cursor, count: usize, what: &str) -> Result<Vec<f32>, String> {
        let bytes = self.value_type.component_bytes(false);
        let n = count * self.value_type.components();
        let raw = c.take(n * bytes, what)?;
        Ok(widen(raw, bytes))
    }

    /// OpenVDB's `readCompressedValues`: `count` values of a node with active entries
    /// `value_mask`, the inactive ones restored from the background and the stored mask.
    fn node_values(
        &mut self,
        c: &mut Cursor,
        count: usize,
        value_mask: &[u64],
        background: &[f32],
        what: &str,
    ) -> Result<Vec<f32>, String> {
        let k = self.value_type.components();
        let mask_compressed = self.compression & COMPRESS_ACTIVE_MASK != 0;
        let metadata = c.array::<1>(what)?[0];
        if metadata > 6 {
            return Err(format!(
                "{what}: value metadata {metadata} (0–6 are defined)"
            ));
        }
        let negative: Vec<f32> = background.iter().map(|v| -v).collect();
        let mut inactive = [
            if metadata == 0 {
                background.to_vec()
            } else {
                negative
            },
            background.to_vec(),
        ];
        if matches!(metadata, 2 | 4 | 5) {
            inactive[0] = self.full_values(c, 1, what)?;
            if metadata == 5 {
                inactive[1] = self.full_values(c, 1, what)?;
            }
        }
        let selection = if matches!(metadata, 3..=5) {
            words(c.take(count / 8, what)?)
        } else {
            vec![0; count / 64]
        };
        let stored = if mask_compressed && metadata != 6 {
            value_mask.iter().map(|w| w.count_ones() as usize).sum()
        } else {
            count
        };
        let width = self.value_type.component_bytes(self.half);
        let raw = if self.half && stored == 0 {
            Vec::new()
        } else {
            self.data(c, stored * k * width, what)?
        };
        let stored_values = widen(&raw, width);
        if stored == count {
            return Ok(stored_values);
        }
        let mut values = Vec::with_capacity(count * k);
        let mut next = stored_values.chunks_exact(k);
        for n in 0..count as u32 {
            if bit(value_mask, n) {
                values.extend_from_slice(next.next().ok_or("too few stored values")?);
            } else {
                values.extend_from_slice(&inactive[usize::from(bit(&selection, n))]);
            }
        }
        Ok(values)
    }

    /// OpenVDB's `readData`: `bytes` bytes, Blosc- or zip-compressed (a size, negative when
    /// stored as is, then the data) or raw.
    fn data(&mut self, c: &mut Cursor, bytes: usize, what: &str) -> Result<Vec<u8>, String> {
        if self.compression & (COMPRESS_BLOSC | COMPRESS_ZIP) == 0 {
            return Ok(c.take(bytes, what)?.to_vec());
        }
        let size = c.i64(what)?;
        if size <= 0 {
            if size.unsigned_abs() != bytes as u64 {
                return Err(format!(
                    "{what}: a chunk of {} bytes where {bytes} were expected",
                    size.unsigned_abs()
                ));
            }
            return Ok(c.take(bytes, what)?.to_vec());
        }
        let packed = c.take(usize::try_from(size).unwrap_or(usize::MAX), what)?;
        if self.compression & COMPRESS_BLOSC != 0 {
            blosc::decompress(packed, bytes).map_err(|e| format!("{what}: {e}"))
        } else {
            let mut out = Vec::with_capacity(bytes);
            flate2::read::ZlibDecoder::new(packed)
                .take(bytes as u64 + 1)
                .read_to_end(&mut out)
                .map_err(|e| format!("{what}: the zip data does not decode: {e}"))?;
            if out.len() != bytes {
                return Err(format!(
                    "{what}: the zip data holds {} bytes, {bytes} expected",
                    out.len()
                ));
            }
            Ok(out)
        }
    }
}

/// Little-endian u64 words of a node mask.
fn words(bytes: &[u8]) -> Vec<u64> {
    bytes
        .chunks_exact(8)
        .map(|w| u64::from_le_bytes(w.try_into().expect("8 bytes")))
        .collect()
}

/// Little-endian components of `width` bytes (2: half, 4: f32, 8: f64) widened to f32.
fn widen(raw: &[u8], width: usize) -> Vec<f32> {
    raw.chunks_exact(width)
        .map(|b| match width {
            2 => half::f16::from_le_bytes([b[0], b[1]]).to_f32(),
            4 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
            _ => f64::from_le_bytes(b.try_into().expect("8 bytes")) as f32,
        })
        .collect()
}

impl Tree {
    /// Reads the tree of `grid` from `bytes`, allocating at most `budget` bytes; leaves
    /// that `keep` says no to have their voxels skipped, not stored.
    pub fn read(
        bytes: &[u8],
        grid: &GridInfo,
        budget: u64,
        keep: impl Fn([i32; 3]) -> bool,
    ) -> Result<Tree, String> {
        let value_type = grid
            .value_type
            .clone()
            .map_err(|t| format!("grid type {t}"))?;
        let mut f = Format {
            value_type,
            half: grid.half,
            compression: grid.compression,
            budget,
        };
        let k = value_type.components();
        let mut c = Cursor::new(bytes, grid.tree_at);
        let buffers = c.i32("the tree's buffer count")?;
        if buffers != 1 {
            return Err(format!("the tree has {buffers} buffers (1 is read)"));
        }
        let background = f.full_values(&mut c, 1, "the background value")?;
        let tiles_count = c.u32("the root")?;
        let children_count = c.u32("the root")?;
        let mut tree = Tree {
            components: k,
            background: background.clone(),
            tiles: HashMap::new(),
            roots: HashMap::new(),
            nodes: Vec::new(),
            charged: 0,
        };
        for _ in 0..tiles_count {
            let origin = [
                c.i32("a root tile")?,
                c.i32("a root tile")?,
                c.i32("a root tile")?,
            ];
            let value = f.full_values(&mut c, 1, "a root tile")?;
            let active = c.array::<1>("a root tile")?[0] != 0;
            f.charge(64, "a root tile")?;
            tree.tiles.insert(origin, (value, active));
        }
        let mut order = Vec::new();
        for _ in 0..children_count {
            let origin = [
                c.i32("a root child")?,
                c.i32("a root child")?,
                c.i32("a root child")?,
            ];
            if origin.iter().any(|o| o & ((1 << ROOT_CHILD_LOG2) - 1) != 0) {
                return Err(format!(
                    "a root child at {origin:?}, not a multiple of 4096"
                ));
            }
            let index = tree.read_internal(&mut c, &mut f, origin, 5, &background)?;
            if tree.roots.insert(origin, index).is_some() {
                return Err(format!("two root children at {origin:?}"));
            }
            order.push((origin, index));
        }
        // Buffers follow in the root's (sorted) order, each subtree depth first.
        order.sort();
        for (_, index) in order {
            tree.read_buffers(&mut c, &mut f, index, &background, &keep)?;
        }
        tree.charged = budget - f.budget;
        Ok(tree)
    }

    /// Reads an internal node's topology (and its children's), returning its index.
    fn read_internal(
        &mut self,
        c: &mut Cursor,
        f: &mut Format,
        origin: [i32; 3],
        log2: u32,
        background: &[f32],
    ) -> Result<usize, String> {
        let what = format!("the node at {origin:?}");
        let entries = 1usize << (3 * log2);
        f.charge((entries * (4 * self.components + 1)) as u64, &what)?;
        let child_mask = words(c.take(entries / 8, &what)?);
        let value_mask = words(c.take(entries / 8, &what)?);
        let values = f.node_values(c, entries, &value_mask, background, &what)?;
        let child_log2 = if log2 == 5 { 7 } else { 3 };
        let index = self.nodes.len();
        self.nodes.push(Node {
            log2,
            child_log2,
            origin,
            child_mask,
            value_mask,
            values,
            children: HashMap::new(),
        });
        let on: Vec<u32> = ones(&self.nodes[index].child_mask).collect();
        for n in on {
            let child_origin = self.nodes[index].child_origin(n);
            let child = if log2 == 5 {
                self.read_internal(c, f, child_origin, 4, background)?
            } else {
                f.charge(64 + 16, "a leaf")?;
                let value_mask = words(c.take(64, "a leaf's mask")?);
                self.nodes.push(Node {
                    log2: 3,
                    child_log2: 0,
                    origin: child_origin,
                    child_mask: Vec::new(),
                    value_mask,
                    values: Vec::new(),
                    children: HashMap::new(),
                });
                self.nodes.len() - 1
            };
            self.nodes[index].children.insert(n, child);
        }
        Ok(index)
    }

    /// Reads the voxels of the leaves under node `index`, in the order they were written.
    fn read_buffers(
        &mut self,
        c: &mut Cursor,
        f: &mut Format,
        index: usize,
        background: &[f32],
        keep: &impl Fn([i32; 3]) -> bool,
    ) -> Result<(), String> {
        let node = &self.nodes[index];
        if node.log2 == 3 {
            let origin = node.origin;
            let what = format!("the leaf at {origin:?}");
            let mask = words(c.take(64, &what)?);
            if mask != node.value_mask {
                return Err(format!("{what}: its two value masks differ"));
            }
            if keep(origin) {
                f.charge((512 * 4 * self.components) as u64, &what)?;
                let values = f.node_values(c, 512, &mask, background, &what)?;
                self.nodes[index].values = values;
            } else {
                // Read to move past it; its values are dropped at once.
                f.node_values(c, 512, &mask, background, &what)?;
            }
            return Ok(());
        }
        let mut children: Vec<(u32, usize)> = node.children.iter().map(|(&n, &i)| (n, i)).collect();
        children.sort();
        for (_, child) in children {
            self.read_buffers(c, f, child, background, keep)?;
        }
        Ok(())
    }

    /// The bytes reading it charged to its budget (its nodes' memory, roughly).
    pub fn bytes(&self) -> u64 {
        self.charged
    }

    /// The value at index `p` and whether it is active.
    pub fn voxel(&self, p: [i32; 3]) -> Voxel<'_> {
        let root = p.map(|c| c & !((1 << ROOT_CHILD_LOG2) - 1));
        let Some(&mut_index) = self.roots.get(&root) else {
            return match self.tiles.get(&root) {
                Some((value, active)) => Voxel {
                    value,
                    active: *active,
                },
                None => Voxel {
                    value: &self.background,
                    active: false,
                },
            };
        };
        let k = self.components;
        let mut node = &self.nodes[mut_index];
        loop {
            let n = node.entry(p);
            match node.children.get(&n) {
                Some(&child) => node = &self.nodes[child],
                None => {
                    let value = node.values.get(n as usize * k..(n as usize + 1) * k);
                    return Voxel {
                        // A leaf outside what was kept reads as the background.
                        value: value.unwrap_or(&self.background),
                        active: bit(&node.value_mask, n),
                    };
                }
            }
        }
    }

    /// The smallest index box holding every active voxel and tile, if any is active.
    pub fn active_bbox(&self) -> Option<([i32; 3], [i32; 3])> {
        let mut bbox: Option<([i32; 3], [i32; 3])> = None;
        let mut add = |lo: [i32; 3], edge_log2: u32| {
            let hi = lo.map(|c| c.saturating_add((1 << edge_log2) - 1));
            bbox = Some(match bbox {
                None => (lo, hi),
                Some((a, b)) => (
                    std::array::from_fn(|i| a[i].min(lo[i])),
                    std::array::from_fn(|i| b[i].max(hi[i])),
                ),
            });
        };
        for (origin, (_, active)) in &self.tiles {
            if *active {
                add(*origin, ROOT_CHILD_LOG2);
            }
        }
        for node in &self.nodes {
            for n in ones(&node.value_mask) {
                if !node.children.contains_key(&n) {
                    add(node.child_origin(n), node.child_log2);
                }
            }
        }
        bbox
    }
}
