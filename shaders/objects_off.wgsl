// Objects variant `off`: no other object blocks this object's shadow rays (a scene of one
// object, or one without shadows).

fn blocked_elsewhere(pixel: vec2<i32>) -> u32 {
    return 0u;
}
