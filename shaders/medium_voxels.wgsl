// Part of the translucent-media pipeline (see `medium_preview.wgsl`):
// the medium's voxels and their exact traversal.

// ---- The medium ---------------------------------------------------------------------------

// Index of voxel (i, j, k) (i, j periodic) of a level, or −1 outside its layers.
fn voxel_index(level: u32, i: i32, j: i32, k: i32) -> i32 {
    let d = medium.levels[level];
    if k < 0 || k >= i32(d.z) {
        return -1;
    }
    return i32(d.w + wrap(i, d.x) + d.x * (wrap(j, d.y) + d.y * u32(k)));
}

// The voxel containing texture point t (voxel units of the level), or −1.
fn voxel_at(level: u32, t: vec3<f32>) -> i32 {
    let c = vec3<i32>(floor(t));
    return voxel_index(level, c.x, c.y, c.z);
}

// Transmittance of `len` voxel lengths of opacity `alpha`: (1 − α)^len.
fn transmit(alpha: f32, len: f32) -> f32 {
    if alpha >= 1.0 {
        return select(1.0, 0.0, len > 0.0);
    }
    return pow(1.0 - alpha, len);
}

// Unit texture-space normal at t, trilinear over voxel centres (x, y periodic, z clamped);
// zero where the gradient vanishes.
fn normal_at(level: u32, t: vec3<f32>) -> vec3<f32> {
    let d = medium.levels[level];
    let f = vec3<f32>(t.x - 0.5, t.y - 0.5, clamp(t.z - 0.5, 0.0, f32(d.z - 1u)));
    let base = floor(f);
    let w1 = f - base;
    let w0 = 1.0 - w1;
    let b = vec3<i32>(base);
    let k0 = i32(min(u32(b.z), d.z - 1u));
    let k1 = i32(min(u32(b.z) + 1u, d.z - 1u));
    // The eight corners written out (loops count against the software driver's budget).
    var n = corner_normal(level, b.x, b.y, k0, w0.x * w0.y * w0.z);
    n += corner_normal(level, b.x + 1, b.y, k0, w1.x * w0.y * w0.z);
    n += corner_normal(level, b.x, b.y + 1, k0, w0.x * w1.y * w0.z);
    n += corner_normal(level, b.x + 1, b.y + 1, k0, w1.x * w1.y * w0.z);
    n += corner_normal(level, b.x, b.y, k1, w0.x * w0.y * w1.z);
    n += corner_normal(level, b.x + 1, b.y, k1, w1.x * w0.y * w1.z);
    n += corner_normal(level, b.x, b.y + 1, k1, w0.x * w1.y * w1.z);
    n += corner_normal(level, b.x + 1, b.y + 1, k1, w1.x * w1.y * w1.z);
    return normalize_or(n, vec3<f32>(0.0));
}

// The weighted normal of one interpolation corner (none at weight 0).
fn corner_normal(level: u32, i: i32, j: i32, k: i32, w: f32) -> vec3<f32> {
    if w == 0.0 {
        return vec3<f32>(0.0);
    }
    return normals[voxel_index(level, i, j, k)].xyz * w;
}

// ---- Voxel traversal ----------------------------------------------------------------------

// The exact voxel walk of a segment (`Medium::walk`): start with `walk_start`, then call
// `walk_next` until it returns false; each call leaves the piece [s0, s1] of voxel `v`.
struct Walk {
    cell: vec3<i32>,
    next: vec3<f32>,
    delta: vec3<f32>,
    step: vec3<i32>,
    s: f32,
    len: f32,
    // The current piece.
    v: i32,
    s0: f32,
    s1: f32,
}

fn walk_start(o: vec3<f32>, d: vec3<f32>, len: f32) -> Walk {
    var w: Walk;
    w.s = 0.0;
    w.len = len;
    let fl = floor(o);
    let moving = d != vec3<f32>(0.0);
    let up = d > vec3<f32>(0.0);
    // Going down from exactly on a voxel face: the voxel below, a whole voxel ahead.
    let on_face = !up & moving & (fl == o);
    w.cell = vec3<i32>(fl) - select(vec3<i32>(0), vec3<i32>(1), on_face);
    w.step = select(vec3<i32>(0), select(vec3<i32>(-1), vec3<i32>(1), up), moving);
    w.delta = select(vec3<f32>(FAR), 1.0 / abs(d), moving);
    let ahead = select((o - fl) / -d, (fl + 1.0 - o) / d, up);
    w.next = select(vec3<f32>(FAR), select(ahead, w.delta, on_face), moving);
    return w;
}

// Advances to the next piece inside the level's layers; false when the segment is done.
// (Vector selects rather than indexing a vector by a varying axis, and loops that leave by
// their conditions: Mesa's software driver of Debian 12 mis-executes both when invocations
// diverge.)
fn walk_next(w: ptr<function, Walk>, level: u32) -> bool {
    let z = i32(medium.levels[level].z);
    var found = false;
    while !found && (*w).s < (*w).len {
        steps += 1u;
        let n = (*w).next;
        // The axis whose face comes first (the first of equals).
        let x = n.x <= n.y && n.x <= n.z;
        let y = !x && n.y <= n.z;
        let axis = vec3<bool>(x, y, !x && !y);
        let end = min(min(n.x, min(n.y, n.z)), (*w).len);
        let c = (*w).cell;
        let start = (*w).s;
        (*w).s = end;
        (*w).cell += select(vec3<i32>(0), (*w).step, axis);
        (*w).next += select(vec3<f32>(0.0), (*w).delta, axis);
        if c.z >= 0 && c.z < z {
            (*w).v = voxel_index(level, c.x, c.y, c.z);
            (*w).s0 = start;
            (*w).s1 = end;
            found = true;
        } else if (c.z < 0 && (*w).step.z <= 0) || (c.z >= z && (*w).step.z >= 0) {
            // Left the layers for good.
            (*w).s = (*w).len;
        }
    }
    return found;
}
