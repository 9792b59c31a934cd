/*
 * checker_filtered.sl -- an antialiased checkerboard in (s, t) that turns
 * smoothly grey as the checks shrink below a pixel.
 *
 * Exercises: filterstep() with the "width" keyword and with an explicit
 * [s1, s2] filter range,
 * Du/Dv and du/dv directly, Deriv(), the filterwidth() macro, the
 * rotate2d statement macro from patterns.h writing two locals, radians(),
 * mod/floor/abs, ?: on colours, and the matte lighting terms.
 */
#include "patterns.h"

surface checker_filtered(
    float Ka = 1, Kd = 1;
    float frequency = 8, angle = 0;
    color blackcolor = color(.05, .05, .05);
    color whitecolor = color(.95, .95, .95);)
{
    float ss, tt;
    rotate2d(s, t, radians(angle), .5, .5, ss, tt);
    ss *= frequency;
    tt *= frequency;

    /* Filter width computed two ways: from Du/Dv, and via Deriv(). */
    float sw = abs(Du(ss) * du) + abs(Dv(ss) * dv);
    float tw = filterwidth(tt);
    float dsdt = abs(Deriv(ss, t));
    sw = max(sw, MINFILTWIDTH);

    /* Fraction of the filter in the first half of each period, per axis. */
    float fs = filterstep(.5, mod(ss, 1), "width", sw);
    float ft = filterstep(.5, mod(tt, 1), mod(tt, 1) + tw);

    /* XOR of the two half-periods; 0.5 means "can't tell". */
    float check = fs + ft - 2 * fs * ft;
    float blurry = smoothstep(.3, .8, max(sw, tw) + .01 * dsdt);
    check = mix(check, .5, blurry);

    color Cc = mix(blackcolor, whitecolor, check);
    Cc = (frequency > 0) ? Cc : whitecolor;

    normal Nf = faceforward(normalize(N), I);
    Oi = Os;
    Ci = Os * Cc * (Ka * ambient() + Kd * diffuse(Nf));
}
