/*
 * uberlight_lite.sl -- a cinematographer's light in the spirit of the
 * "uber" lights of production: a superelliptical cross-section, barn
 * doors, near/far cut-ons, a noise "cookie" breaking up the beam, and
 * shaping functions factored out as user functions.
 *
 * Exercises: illuminate(from), user functions with several parameter
 * groups called from inside illuminate, transform() into "shader" space,
 * pow()/abs() superellipse, smoothstep() edges, noise() on a point,
 * the boxstep() macro from patterns.h, output varying and uniform
 * parameters, __nonspecular and __category, and ?:.
 */
#include "patterns.h"

/* Superellipse membership: 1 inside, 0 outside, soft over "edge". */
float superellipse(float x, y, a, b, roundness, edge)
{
    float d;
    if (roundness < 1.0e-3)
        d = max(abs(x) / a, abs(y) / b);
    else
        d = pow(pow(abs(x) / a, 2 / roundness) + pow(abs(y) / b, 2 / roundness),
                roundness / 2);
    return 1 - smoothstep(1 - edge, 1, d);
}

/* Near and far cut-ons with soft edges. */
float clipdepth(float z, nearedge, faredge, width)
{
    return smoothstep(nearedge - width, nearedge, z)
           * (1 - smoothstep(faredge, faredge + width, z));
}

light uberlight_lite(
    float intensity = 1;
    color lightcolor = 1;
    point from = point "shader" (0, 0, 0);
    float width = .5, height = .5, roundness = 1, edgewidth = .1;
    float nearedge = .1, faredge = 1e6, cutonwidth = .1;
    float barnleft = -1, barnright = 1, barntop = 1, barnbottom = -1;
    float cookiefreq = 4, cookiedensity = 0;
    uniform string __category = "specular,key";
    output uniform float __nonspecular = 0;
    output varying float shapeout = 0;)
{
    illuminate(from) {
        point Pl = transform("shader", Ps);
        float z = max(zcomp(Pl), 1.0e-4);
        float x = xcomp(Pl) / z, y = ycomp(Pl) / z;

        float shape = superellipse(x, y, width, height, roundness, edgewidth);
        shape *= clipdepth(zcomp(Pl), nearedge, faredge, cutonwidth);

        /* Barn doors are flat cut-offs in the projected plane. */
        shape *= boxstep(barnleft - .02, barnleft, x) * boxstep(-barnright - .02, -barnright, -x);
        shape *= boxstep(barnbottom - .02, barnbottom, y) * boxstep(-barntop - .02, -barntop, -y);

        float cookie = (cookiedensity > 0)
                       ? 1 - cookiedensity * smoothstep(.4, .6, noise(point(x, y, 0) * cookiefreq))
                       : 1;
        shapeout = shape * cookie;
        Cl = intensity * lightcolor * shapeout / (L . L);
    }
}
