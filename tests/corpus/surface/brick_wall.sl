/*
 * brick_wall.sl -- running-bond bricks with mortar joints, antialiased
 * with box-filtered pulse trains, per-brick colour variation, and a
 * slight bump into the mortar.
 *
 * Exercises: #include "patterns.h" (filteredpulsetrain, whichtile, repeat,
 * boxstep), filterwidth() of s and t, whichtile with a half-brick offset on
 * odd rows (mod on a float in a ?: expression), cellnoise on a point built
 * from tile indices, noise(), calculatenormal() for bump mapping in a
 * surface shader, normal arithmetic, and the standard plastic terms.
 */
#include "patterns.h"

surface brick_wall(
    float Ka = 1, Kd = .9, Ks = .05, roughness = .25;
    color brickcolor = color(.6, .14, .08);
    color mortarcolor = color(.55, .53, .5);
    float brickwidth = .25, brickheight = .08, mortarthickness = .01;
    float colorvariation = .2;
    float bumpdepth = .01;)
{
    uniform float bmwidth = brickwidth + mortarthickness;
    uniform float bmheight = brickheight + mortarthickness;

    float sbrick = s / bmwidth;
    float tbrick = t / bmheight;
    float row = whichtile(tbrick, 1);

    /* Shift every other row by half a brick. */
    sbrick += (mod(row, 2) == 1) ? .5 : 0;
    float col = whichtile(sbrick, 1);

    /* Brick coverage: 1 inside the brick, 0 in the joint, box-filtered. */
    float sw = filterwidth(sbrick);
    float tw = filterwidth(tbrick);
    float inbrick_s = filteredpulsetrain(brickwidth / bmwidth, 1,
                                         sbrick + mortarthickness / (2 * bmwidth), sw);
    float inbrick_t = filteredpulsetrain(brickheight / bmheight, 1,
                                         tbrick + mortarthickness / (2 * bmheight), tw);
    float brickness = inbrick_s * inbrick_t;

    /* Per-brick colour: each (col, row) gets its own random offset. */
    float rnd = float cellnoise(point(col, row, 0));
    color Cb = brickcolor * (1 - colorvariation / 2 + colorvariation * rnd);
    Cb *= .85 + .3 * noise(point(s * 40, t * 40, row));

    /* Bump: mortar sits lower than the brick faces, whose edges are rounded. */
    float edge = boxstep(0, .15, repeat(sbrick, 1)) * boxstep(0, .15, 1 - repeat(sbrick, 1));
    float height = bumpdepth * brickness * (.7 + .3 * edge);
    normal Nn = normalize(N);
    point Pb = P + height * Nn;
    normal Nb = normalize(calculatenormal(Pb));
    normal Nf = faceforward(Nb, I);
    vector V = -normalize(I);

    color Ct = mix(mortarcolor, Cb, brickness);
    Oi = Os;
    Ci = Os * (Ct * (Ka * ambient() + Kd * diffuse(Nf))
               + Ks * brickness * specular(Nf, V, roughness));
}
