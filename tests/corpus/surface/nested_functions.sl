/*
 * nested_functions.sl -- a "polka dot quilt": each patch of the quilt gets
 * a randomly coloured dot, with the work split into functions defined
 * inside the shader body and inside other functions.
 *
 * Exercises: functions defined inside a shader body; a function defined
 * inside another nested function; extern declarations reaching shader
 * globals (P, s, t), shader parameters and enclosing locals; a nested
 * function that assigns to an enclosing variable through extern; output
 * parameters on nested functions; void and value-returning nested
 * functions; attribute("identifier:name") for a per-object seed;
 * cellnoise and noise.
 */
#include "config.h"

surface nested_functions(
    float Ka = 1, Kd = .8, Ks = .3, roughness = .15;
    float patches = 5, dotradius = .3, fuzz = .02;
    color quiltcolor = color(.9, .85, .75);)
{
    float myvar = 0;
    float seed = 0;
    uniform string objname = "";

    /* A per-object seed, chosen from the object's name. */
    if (attribute("identifier:name", objname) != 0) {
        if (match("quilt", objname) != 0)
            seed = 17;
        else
            seed = 3;
    }

    /* Patch coordinates: which patch (output) and where inside it. */
    void patchcoords(output float ps, pt, col, row)
    {
        extern float s, t;
        extern uniform float patches;
        col = floor(s * patches);
        row = floor(t * patches);
        ps = s * patches - col;
        pt = t * patches - row;
    }

    /* Dot coverage at (ps, pt), with a random offset per patch. */
    float dotcoverage(float ps, pt, col, row)
    {
        extern uniform float dotradius, fuzz;
        extern float seed;

        /* Random jitter of the dot centre, nested one level deeper. */
        float jitter(float which)
        {
            extern float col, row, seed;
            return .25 * (float cellnoise(point(col, row, which + seed)) - .5);
        }

        float cx = .5 + jitter(1), cy = .5 + jitter(2);
        float d = sqrt(SQR(ps - cx) + SQR(pt - cy));
        return 1 - smoothstep(dotradius - fuzz, dotradius, d);
    }

    /* Accumulate a wobble into the enclosing variable myvar. */
    void addwobble(float amount)
    {
        extern point P;
        extern float myvar;
        myvar += amount * noise(P * 4);
    }

    float ps, pt, col, row;
    patchcoords(ps, pt, col, row);
    float dotmask = dotcoverage(ps, pt, col, row);
    addwobble(.2);
    addwobble(.1);

    color dotcolor = color "hsv" (float cellnoise(point(col, row, seed)), .6, .9);
    color C = mix(quiltcolor * (.9 + myvar), dotcolor, dotmask);

    normal Nf = faceforward(normalize(N), I);
    vector V = -normalize(I);
    Oi = Os;
    Ci = Os * (C * (Ka * ambient() + Kd * diffuse(Nf))
               + Ks * dotmask * specular(Nf, V, roughness));
}
