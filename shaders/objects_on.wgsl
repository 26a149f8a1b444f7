// Objects variant `on`: a scene of several objects with shadows (`crates/mesobake-render/src/objects.rs`,
// the specification), whatever each object's technique. Every object's module draws its own
// hits into the shared hit targets (`hit_targets.wgsl`), then three full-screen passes run,
// each object's pipeline in turn: `fs_start` writes the shadow-ray start of each of its own
// pixels (its technique's `own_start`), `fs_occlude` traces this object from every other
// object's start towards each light and sets the light's bit in `blocked` where it blocks the
// ray before the light (its technique's `occludes`: `ObjectRenderer::occludes`), and the
// shading pass lets a light reach the pixel only where no other object set its bit
// (`blocked_elsewhere`). At most 32 lights (one bit each).

// Per pixel, the shadow-ray start of its hit (xyz; w = 1, 0 where no hit), from `fs_start`.
@group(0) @binding(9) var hit_starts: texture_2d<f32>;
// Per pixel, bit l set where another object blocks light l; cleared each frame.
@group(0) @binding(10) var<storage, read_write> blocked: array<atomic<u32>>;

fn blocked_elsewhere(pixel: vec2<i32>) -> u32 {
    return atomicLoad(&blocked[pixel_index(pixel)]);
}

// The shadow-ray start of each pixel whose hit is this object's.
@fragment
fn fs_start(@builtin(position) frag: vec4<f32>) -> @location(0) vec4<f32> {
    let start = own_start(vec2<i32>(frag.xy));
    if start.w == 0.0 {
        discard;
    }
    return start;
}

// This object against every other object's shadow rays: the bits of the lights it blocks,
// into `blocked`.
@fragment
fn fs_occlude(@builtin(position) frag: vec4<f32>) {
    let pixel = vec2<i32>(frag.xy);
    let start = textureLoad(hit_starts, pixel, 0);
    if start.w == 0.0 || u32(textureLoad(hit_views, pixel, 0).w) == view.object {
        return;
    }
    let p = textureLoad(hit_points, pixel, 0).xyz;
    var bits = 0u;
    for (var l = 0u; l < min(view.light_count, 32u); l++) {
        let light = lights[l];
        if light.kind == 2u {
            continue;
        }
        let inc = light_incidence(light, p);
        if inc.valid && occludes(start.xyz, inc.dir, inc.distance) {
            bits |= 1u << l;
        }
    }
    if bits != 0u {
        atomicOr(&blocked[pixel_index(pixel)], bits);
    }
}
