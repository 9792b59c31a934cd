/*
 * brick_mortar.sl -- displacement companion to brick_wall.sl: bricks stand
 * out of recessed mortar joints, with chipped edges and a rough mortar
 * surface, all antialiased.
 *
 * Exercises: #include "patterns.h" with filteredpulse() and whichtile(),
 * filterwidth() on s and t, noise() and cellnoise(), smoothstep(),
 * ?: on a mod() test, the standard displacement idiom, and an output
 * varying parameter so the surface can tell brick from mortar.
 */
#include "patterns.h"

displacement brick_mortar(
    float Km = .01;
    float brickwidth = .25, brickheight = .08, mortarthickness = .01;
    float chipping = .3;
    output varying float inmortar = 0;)
{
    uniform float bmwidth = brickwidth + mortarthickness;
    uniform float bmheight = brickheight + mortarthickness;
    uniform float mw = mortarthickness / bmwidth;
    uniform float mh = mortarthickness / bmheight;

    float ss = s / bmwidth, tt = t / bmheight;
    float row = whichtile(tt, 1);
    ss += (mod(row, 2) == 1) ? .5 : 0;
    float col = whichtile(ss, 1);
    ss -= col;
    tt -= row;

    /* Inside-brick coverage, box-filtered. */
    float ws = filterwidth(ss), wt = filterwidth(tt);
    float brick = filteredpulse(mw / 2, 1 - mw / 2, ss, ws)
                  * filteredpulse(mh / 2, 1 - mh / 2, tt, wt);

    /* Chip the brick edges, differently for each brick. */
    float seed = float cellnoise(point(col, row, 1));
    float chips = chipping * noise(point(s, t, seed) * 60);
    float edgedist = min(min(ss, 1 - ss) * bmwidth, min(tt, 1 - tt) * bmheight);
    brick *= smoothstep(0, mortarthickness * (1 + 3 * chips), edgedist);

    /* Mortar is rough; brick faces are flat. */
    float rough = (1 - brick) * .3 * noise(point(s, t, 0) * 200);
    inmortar = 1 - brick;

    P += Km * (brick + rough) * normalize(N);
    N = calculatenormal(P);
}
