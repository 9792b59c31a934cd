//! The derivative operators on screen-space derivatives (`docs/packet-abi.md`, "Derivatives").
//!
//! A ray tracer knows, per shading point, the derivatives of values with respect to the screen
//! (`f_x`, `f_y`, carried by forward-mode differentiation from the renderer's ray differentials).
//! RSL's derivatives are with respect to the surface parameters: with the screen derivatives of the
//! parameters (`u_x`, `u_y`, `v_x`, `v_y`), the chain rule `f_x = f_u u_x + f_v v_x`,
//! `f_y = f_u u_y + f_v v_y` inverts to the formulas below. The JIT evaluates the same operations in
//! the same order (so they agree bit for bit).

/// Below this `|J|` (the screen-to-parameter Jacobian's determinant) the parameters do not vary
/// over the pixel in two independent directions: `Du` and `Dv` are 0 rather than huge.
pub const MIN_JACOBIAN: f32 = 1e-20;

/// The parameter derivatives of one float: `(Du(f), Dv(f))` from `f_x, f_y` and the parameters'
/// screen derivatives `[u_x, u_y, v_x, v_y]`:
/// `J = u_x v_y - u_y v_x`, `Du = (f_x v_y - f_y v_x) / J`, `Dv = (f_y u_x - f_x u_y) / J`, both 0
/// when `!(|J| > MIN_JACOBIAN)` (NaN included).
pub fn du_dv(fx: f32, fy: f32, uv: [f32; 4]) -> (f32, f32) {
    let [ux, uy, vx, vy] = uv;
    let j = ux * vy - uy * vx;
    if j.is_nan() || j.abs() <= MIN_JACOBIAN {
        return (0.0, 0.0);
    }
    ((fx * vy - fy * vx) / j, (fy * ux - fx * uy) / j)
}

/// One term of `Deriv(num, den) = Du(num) / Du(den) + Dv(num) / Dv(den)`: 0 where the
/// denominator's derivative is 0.
pub fn ratio(num: f32, den: f32) -> f32 {
    if den == 0.0 {
        0.0
    } else {
        num / den
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inverts_the_chain_rule() {
        // u = 2x + y, v = x - y (screen derivatives), f = 3u + 5v: f_x = 6 + 5, f_y = 3 - 5.
        let uv = [2.0, 1.0, 1.0, -1.0];
        assert_eq!(du_dv(11.0, -2.0, uv), (3.0, 5.0));
        assert_eq!(du_dv(1.0, 1.0, [1.0, 2.0, 2.0, 4.0]), (0.0, 0.0));
        assert_eq!(ratio(1.0, 0.0), 0.0);
    }
}
