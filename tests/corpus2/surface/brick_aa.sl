/*
 * brick_aa.sl -- running-bond brick wall with antialiased mortar,
 * per-brick colour variation, speckle, and grooved mortar joints
 * produced by perturbing the shading normal inside the surface shader.
 *
 * Exercises: the filterwidth() macro on s/t-derived coordinates,
 * filteredpulse() from a header, floor()/mod() brick indexing with a
 * half-brick offset on odd rows, cellnoise(x, y) per brick returning
 * float and colour, noise() speckle, a bump in a surface shader through
 * calculatenormal(P - amp * normalize(N)) and normalize(), with the
 * geometric-normal correction (Ng vs N), and mix() between colours.
 */
#include "aa_filters.h"
#include "fractals.h"

surface brick_aa(
    float Ka = 1, Kd = 1;
    color brickcolor = color(0.6, 0.12, 0.08);
    color mortarcolor = color(0.55, 0.53, 0.5);
    float brickwidth = 0.25, brickheight = 0.08, mortarthickness = 0.01;
    float colorvariation = 0.25, speckle = 0.15, specklefreq = 120;
    float groovedepth = 0.005;)
{
    uniform float bmwidth = brickwidth + mortarthickness;
    uniform float bmheight = brickheight + mortarthickness;
    uniform float mwf = mortarthickness * 0.5 / bmwidth;
    uniform float mhf = mortarthickness * 0.5 / bmheight;

    float ss = s / bmwidth;
    float tt = t / bmheight;
    float row = floor(tt);
    if (mod(row, 2) == 1)
        ss += 0.5;
    float col = floor(ss);

    /* Antialiased in-brick masks; fractional coordinates in [0,1). */
    float fs = ss - col, ft = tt - row;
    float fws = filterwidth(ss), fwt = filterwidth(tt);
    float inbrick = filteredpulse(mwf, 1 - mwf, fs, fws)
                  * filteredpulse(mhf, 1 - mhf, ft, fwt);

    /* Per-brick variation. */
    float r = float cellnoise(col + 0.5, row + 0.5);
    color bc = brickcolor * (1 + colorvariation * (r - 0.5));
    bc *= color cellnoise(col * 7 + 1, row * 3 + 2) * 0.2 + 0.9;
    float spk = snoise(transform("shader", P) * specklefreq);
    bc *= 1 - speckle * smoothstep(0.3, 0.7, spk);

    color Ct = mix(mortarcolor, bc, inbrick);

    /* Grooves: push mortar back along the normal and recompute it. */
    normal Nbump = N;
    if (groovedepth != 0) {
        normal delta = normalize(N) - normalize(Ng);
        point Pb = P - groovedepth * (1 - inbrick) * normalize(N);
        Nbump = normalize(calculatenormal(Pb)) + delta;
    }
    normal Nf = faceforward(normalize(Nbump), I);

    Oi = Os;
    Ci = Os * Ct * (Ka * ambient() + Kd * diffuse(Nf));
}
