/*
 * planet_terrain.sl -- a whole planet from a sphere: continents and
 * mountains from fBm over the surface direction, oceans below a water
 * level with their own highlight, altitude-dependent vegetation colour
 * from a colour spline over an array, and polar ice caps that reach
 * lower on high ground.
 *
 * Exercises: fBm() and ridged() from noises.h, transform() to "object"
 * space and normalize() to get a direction, a colour array parameter fed
 * to spline("catmull-rom", x, array), float splines with and without a
 * basis, the ?: operator, && and || conditions, output varying
 * parameters (altitude, iswater), LocIllumGlossy from material.h for
 * the water glint, and abs()/ycomp() for latitude.
 */
#include "noises.h"
#include "material.h"

surface planet_terrain(
    float Ka = .1, Kd = 1, Kwater = .8;
    float continentfreq = 1.5, mountainfreq = 6, mountainheight = .35;
    float waterlevel = .0;
    float icelatitude = .8, icealtitude = .5;
    color oceandeep = color(.01, .05, .2);
    color oceanshallow = color(.05, .25, .4);
    color landcolors[6] = {color(.76, .7, .5), color(.76, .7, .5),
                           color(.2, .45, .15), color(.35, .4, .2),
                           color(.45, .4, .35), color(.9, .9, .9)};
    output varying float altitude = 0;
    output varying float iswater = 0;)
{
    point Po = transform("object", P);
    vector dir = normalize(Po - point(0, 0, 0));
    point Pd = point(0, 0, 0) + dir;

    /* Continents from fBm; mountains from ridged noise on the land. */
    float land = fBm(Pd * continentfreq, 6, 2, .5);
    float mountains = ridged(Pd * mountainfreq, 5, 2.1, .5, 1);
    altitude = land + ((land > waterlevel) ? mountainheight * mountains * (land - waterlevel) : 0);

    float latitude = abs(ycomp(dir));
    float icefactor = spline("linear", latitude, 0, 0, 0, .6, 1, 1)
                      + spline(clamp(altitude / icealtitude, 0, 1), 0, 0, .2, .7, 1, 1);

    normal Nf = faceforward(normalize(N), I);
    vector V = -normalize(I);
    color C;
    color glint = 0;

    if (altitude <= waterlevel) {
        iswater = 1;
        float depthbelow = clamp((waterlevel - altitude) * 4, 0, 1);
        C = mix(oceanshallow, oceandeep, depthbelow);
        glint = Kwater * LocIllumGlossy(Nf, V, .05, .3);
    } else {
        iswater = 0;
        float h = clamp((altitude - waterlevel) / (1 - waterlevel), 0, 1);
        C = color spline("catmull-rom", h, landcolors);
    }

    /* Ice on the poles, and on high ground nearer the equator. */
    if (icefactor > icelatitude || (iswater < 1 && altitude > icealtitude && latitude > .4))
        C = mix(C, color(.95, .97, 1), smoothstep(icelatitude, icelatitude + .1, icefactor + .05));

    Oi = Os;
    Ci = Os * (C * (Ka * ambient() + Kd * diffuse(Nf)) + glint);
}
