// GDM queries of the `occupancy` codec (`OccupancyLookup` in
// crates/mesobake-render/src/gdm_lookup.rs, which runs the traversal of
// crates/mesobake-bake/src/gdm/volume_caster.rs): the voxels ray-marched exactly along the
// query, crossing empty space in boxes whose size the stored distances give.

// Per voxel: 0 solid, else the Chebyshev distance in voxels to the nearest solid voxel
// (periodic in x and y, layers outside the grid empty; 255 means at least 255).
@group(1) @binding(0) var occupancy: texture_3d<u32>;

// Most empty boxes one march crosses; a march that needs more reports an escape (grid
// directions cross at most a few dozen boxes: the bound only stops near-horizontal rays).
const MAX_MARCH_STEPS: u32 = 1024u;
// Stands for "never" in plane-crossing times.
const NEVER: f32 = 3.0e38;

fn distance_at(cell: vec3<i32>, dims: vec3<u32>) -> u32 {
    let i = wrap(cell.x, dims.x);
    let j = wrap(cell.y, dims.y);
    return textureLoad(occupancy, vec3<i32>(i32(i), i32(j), cell.z), 0).r;
}

// The distance to the first solid voxel along o + s·v (unit v) for 0 ≤ s ≤ max_s, or −1
// when the ray leaves the volume through its top or bottom plane, or passes max_s, first.
// Written on whole vectors (no per-axis loop): the axis the ray leaves a box by is the first
// of x, y, z with the smallest crossing time, as in the CPU traversal.
fn march(o_in: vec3<f32>, v: vec3<f32>, max_s: f32) -> f32 {
    let dims = textureDimensions(occupancy);
    let nz = i32(dims.z);
    let o = vec3<f32>(o_in.xy, clamp(o_in.z, 0.0, f32(dims.z)));
    let f = floor(o);
    let moving = v != vec3<f32>(0.0);
    let up = v > vec3<f32>(0.0);
    let dir = select(vec3<i32>(-1), vec3<i32>(1), up);
    let inv = 1.0 / select(vec3<f32>(1.0), v, moving);
    // A start on a voxel plane, moving down that axis, is in the voxel behind the plane.
    var cell = vec3<i32>(f) - vec3<i32>((o == f) & (v < vec3<f32>(0.0)));
    // The distance stored at `cell`, loaded once per cell entered.
    var here = 1u;
    if cell.z >= 0 && cell.z < nz {
        here = distance_at(cell, dims);
        if here == 0u {
            return 0.0;
        }
    }
    for (var step = 0u; step < MAX_MARCH_STEPS; step++) {
        if cell.z < 0 || cell.z >= nz {
            return -1.0;
        }
        let r = i32(max(here, 1u));
        // Leave the empty box of voxels within r − 1 of `cell` (clipped to the volume in z).
        var plane = select(cell - vec3<i32>(r - 1), cell + vec3<i32>(r), up);
        plane.z = clamp(plane.z, 0, nz);
        let t = select(vec3<f32>(NEVER), (vec3<f32>(plane) - o) * inv, moving);
        let t_exit = min(t.x, min(t.y, t.z));
        if t_exit > max_s {
            return -1.0;
        }
        let exit_x = t.x <= t.y && t.x <= t.z;
        let exit_y = !exit_x && t.y <= t.z;
        let exit = vec3<bool>(exit_x, exit_y, !exit_x && !exit_y);
        // The voxel entered next: one past the box on the exit axis, the crossing point's
        // voxel (within the box) on the others.
        let inside = clamp(
            vec3<i32>(floor(o + t_exit * v)),
            cell - vec3<i32>(r - 1),
            cell + vec3<i32>(r - 1),
        );
        cell = select(inside, cell + dir * r, exit);
        if cell.z >= 0 && cell.z < nz {
            here = distance_at(cell, dims);
            if here == 0u {
                return t_exit;
            }
        }
    }
    return -1.0;
}

// The hit distance along the texture-space segment, or −1 when the ray leaves it first.
fn segment_hit(start: vec3<f32>, view_dir: vec3<f32>, d_t: f32) -> f32 {
    let d = march(start, view_dir, d_t);
    return select(-1.0, d, d >= 0.0 && d < d_t);
}

// Whether the ray from `origin` along the unit texture direction `l` leaves the volume.
fn escapes(origin: vec3<f32>, l: vec3<f32>) -> bool {
    return march(origin, l, NEVER) < 0.0;
}
