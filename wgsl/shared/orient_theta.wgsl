// θ = ½ atan2 of a double-angle vector, in [0, π) (x right, y down); 0 for the zero vector.
// The CPU side is `stages::orient_resolve::resolve_theta`.

fn resolve_theta(dx: f32, dy: f32) -> f32 {
    let pi = 3.14159265358979;
    var theta = 0.0;
    if dx != 0.0 || dy != 0.0 {
        theta = 0.5 * atan2(dy, dx);
        if theta < 0.0 {
            theta = theta + pi;
        }
        if theta >= pi {
            theta = theta - pi;
        }
    }
    return theta;
}
