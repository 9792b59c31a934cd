/*
 * window_gobo.sl -- sunlight through a procedural window: a distant
 * light whose beam is masked by mullions and panes computed in a
 * "window" plane, placed by a projection matrix parameter.  Dirt on the
 * glass is a little fBm, and the panes may be tinted per pane.
 *
 * Exercises: matrix shader parameters defaulting to 1 (identity),
 * a matrix built from 16 values, matrix * matrix, transform(matrix, p),
 * vtransform("shader", v), determinant() to reject singular matrices,
 * comp(m, row, col), solar(axis, angle) with a non-zero spread,
 * cellnoise() per pane, floor()/mod() pane indexing, smoothstep-soft
 * mullion edges, a uniform-valued ?: on matrices, and the __nondiffuse /
 * __nonspecular outputs.
 */
#include "fractals.h"

light window_gobo(
    float intensity = 1;
    color lightcolor = color(1, 0.95, 0.85);
    vector direction = vector "shader" (0, -1, 1);
    float spread = 0.5;                   /* degrees of sun disc */
    matrix windowxform = 1;               /* world -> window plane */
    float panesx = 3, panesy = 4;         /* panes across and down */
    float framewidth = 0.04, blurwidth = 0.01;
    float dirt = 0.2, tintvariation = 0.1;
    output uniform float __nondiffuse = 0;
    output uniform float __nonspecular = 0;)
{
    /*
     * Flip y and recentre: a fixed matrix written out element by element
     * (row-major, points are row vectors as in RenderMan).
     */
    uniform matrix flipcenter = (1, 0, 0, 0,
                                 0, -1, 0, 0,
                                 0, 0, 1, 0,
                                 0.5, 0.5, 0, 1);
    uniform matrix useful = (determinant(windowxform) != 0) ? windowxform : matrix "world" 1;
    uniform matrix proj = useful * flipcenter;
    uniform float skew = comp(proj, 1, 0) + comp(proj, 0, 1);
    uniform vector axis = normalize(vtransform("shader", "current", direction));

    solar(axis, radians(spread)) {
        point Pw = transform(proj, Ps);
        /* Project along the light direction onto z = 0 of the window. */
        vector Dw = vtransform(proj, axis);
        float tz = (abs(zcomp(Dw)) > 1.0e-6) ? zcomp(Pw) / zcomp(Dw) : 0;
        float wx = xcomp(Pw) - tz * xcomp(Dw) + 0.01 * skew;
        float wy = ycomp(Pw) - tz * ycomp(Dw);

        float inside = step(0, wx) * step(wx, 1) * step(0, wy) * step(wy, 1);

        /* Pane coordinates and index. */
        float px = wx * panesx, py = wy * panesy;
        float fx = mod(px, 1), fy = mod(py, 1);
        float paneid = floor(px) + 17 * floor(py);
        float hw = framewidth / 2;
        float glass = smoothstep(hw - blurwidth, hw + blurwidth, fx)
                    * (1 - smoothstep(1 - hw - blurwidth, 1 - hw + blurwidth, fx))
                    * smoothstep(hw - blurwidth, hw + blurwidth, fy)
                    * (1 - smoothstep(1 - hw - blurwidth, 1 - hw + blurwidth, fy));

        /* Per-pane tint and a little dirt. */
        color tint = 1 - tintvariation * (color cellnoise(paneid));
        float grime = 1 - dirt * clamp(0.5 + 0.5 * fBm_aa(point(wx, wy, 0) * 8, 0, 4, 2, 0.5), 0, 1);

        Cl = intensity * lightcolor * tint * (inside * glass * grime);
    }
}
