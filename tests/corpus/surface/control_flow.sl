/*
 * control_flow.sl -- a "scattered coins" pattern: for each point, search
 * the neighbouring cells for a coin that covers it, taking the first hit.
 * Written to use every loop and branch construct of the language.
 *
 * Exercises: nested for loops with "break 2" (stop both loops on a hit)
 * and "continue 2" (skip the rest of a column), plain break and continue,
 * a while loop with a counter, the ?: operator, &&, || and ! in
 * conditions, all compound assignments (+= -= *= /=), unary minus,
 * functions with early return statements, and uniform vs varying locals.
 */
#include "config.h"

/* Sign of x as -1, 0 or 1, with an early return for zero. */
float signum(float x)
{
    if (x == 0)
        return 0;
    return (x > 0) ? 1 : -1;
}

/* Number of times x can be halved before dropping below lim. */
float halvings(float x, lim)
{
    float n = 0, y = x;
    while (y >= lim) {
        y /= 2;
        n += 1;
        if (n > 30)
            break;
    }
    return n;
}

surface control_flow(
    float Ka = 1, Kd = .9;
    float cellsize = .1, coinradius = .08, density = .7;
    color coincolor = color(.85, .7, .3);
    color tablecolor = color(.2, .3, .2);)
{
    float ss = s / cellsize, tt = t / cellsize;
    float cs = floor(ss), ct = floor(tt);
    float hit = 0, ring = 0;
    float i, j;

    for (i = -1; i <= 1; i += 1) {
        /* Columns entirely out of range cannot hold a covering coin. */
        if (cs + i < 0)
            continue;
        for (j = -1; j <= 1; j += 1) {
            point cell = point(cs + i, ct + j, 0);
            if (float cellnoise(cell) > density)
                continue;
            if (ct + j < 0 || !(ct + j < 1 / cellsize))
                continue 2;
            float cx = cs + i + .5 + .3 * signum(float cellnoise(cell + 5) - .5);
            float cy = ct + j + .5;
            float d = sqrt(SQR(ss - cx) + SQR(tt - cy)) * cellsize;
            if (d < coinradius) {
                hit = 1;
                ring = (d > .8 * coinradius) ? 1 : 0;
                break 2;
            }
        }
    }

    /* Exercise the remaining compound assignments on the coin shade. */
    float shade = 1;
    shade *= (ring > 0) ? .7 : 1;
    shade -= .1 * halvings(1 / max(cellsize, .001), 1) / 10;
    shade /= 1 + .2 * (1 - hit);
    shade = -(-shade);

    color C = (hit > 0 && !(shade < 0)) ? coincolor * shade : tablecolor;

    normal Nf = faceforward(normalize(N), I);
    Oi = Os;
    Ci = Os * C * (Ka * ambient() + Kd * diffuse(Nf));
}
