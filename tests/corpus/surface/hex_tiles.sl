/*
 * hex_tiles.sl -- hexagonal floor tiles with grout, per-tile colour
 * variation chosen from a palette, and slightly bevelled tile edges.
 *
 * Exercises: hexagonal lattice arithmetic with floor() and a search over
 * candidate centres held in local point arrays, a for loop with continue,
 * a user function with output parameters returning the tile centre and
 * edge distance, local and parameter colour arrays, PaletteStep() from
 * palettes.h, filterwidth(), calculatenormal() bump in a surface shader,
 * sqrt(), min(), and mix().
 */
#include "palettes.h"
#include "filterwidth.h"

/*
 * Nearest hexagon centre to (x, y) in a lattice of unit spacing, and the
 * distance from (x, y) to the tile's edge (0 on the edge, positive inside).
 */
void hexcell(float x, y; output float cx, cy, edgedist)
{
    uniform float h = sqrt(3) / 2;
    float row = floor(y / h);
    point cands[4];
    float i, best = 1e9, bx = 0, by = 0;

    cands[0] = point(floor(x) + .5 * mod(row, 2), row * h, 0);
    cands[1] = cands[0] + vector(1, 0, 0);
    cands[2] = point(floor(x + .5) + .5 * mod(row + 1, 2) - .5, (row + 1) * h, 0);
    cands[3] = cands[2] + vector(1, 0, 0);

    for (i = 0; i < 4; i += 1) {
        float ddx = x - xcomp(cands[i]), ddy = y - ycomp(cands[i]);
        float d2 = ddx * ddx + ddy * ddy;
        if (d2 >= best)
            continue;
        best = d2;
        bx = xcomp(cands[i]);
        by = ycomp(cands[i]);
    }
    cx = bx;
    cy = by;

    /* Distance to the nearest of the three pairs of parallel edges. */
    float dx = abs(x - bx), dy = abs(y - by);
    float e1 = .5 - dx;
    float e2 = .5 - (dx * .5 + dy * h);
    edgedist = min(e1, e2);
}

surface hex_tiles(
    float Ka = 1, Kd = .8, Ks = .4, roughness = .1;
    float frequency = 10, groutwidth = .04, bevel = .03;
    color palette[3] = {color(.8, .78, .72), color(.7, .6, .5), color(.25, .3, .35)};
    color groutcolor = color(.35, .33, .3);)
{
    float cx, cy, edge;
    hexcell(s * frequency, t * frequency, cx, cy, edge);

    float fw = filterwidth(edge);
    float intile = smoothstep(groutwidth - fw, groutwidth + fw, edge);
    float pick = float cellnoise(point(cx * 7.1, cy * 3.3, 0));
    color Ctile = PaletteStep(palette, 3, pick);
    Ctile *= .9 + .2 * float cellnoise(point(cx, cy, 1));

    /* Bevelled edges: raise the tile, rounding over the last "bevel". */
    float height = smoothstep(groutwidth, groutwidth + bevel, edge) * .005;
    normal Nb = calculatenormal(P + height * normalize(N));
    normal Nf = faceforward(normalize(Nb), I);
    vector V = -normalize(I);

    color C = mix(groutcolor, Ctile, intile);
    Oi = Os;
    Ci = Os * (C * (Ka * ambient() + Kd * diffuse(Nf))
               + Ks * intile * specular(Nf, V, roughness));
}
