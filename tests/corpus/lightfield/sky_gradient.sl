/*
 * sky_gradient.sl -- radiance for rays that leave the scene: a procedural
 * sky with a zenith-to-horizon gradient, a darker ground, a sun disc with
 * a soft glow, and thin noise clouds.
 *
 * Exercises: the "lightfield" shader type (an rtsl extension) reading
 * the ray direction I and origin E and writing Ci and Oi; vtransform()
 * to "world"; vector "world" casts; the dot product; pow(), exp(),
 * smoothstep(); noise on a point built from the direction; mix() of
 * colours; ?: on colours.
 */
#include "noises.h"

lightfield sky_gradient(
    color zenithcolor = color(.15, .3, .75);
    color horizoncolor = color(.7, .8, .95);
    color groundcolor = color(.25, .22, .2);
    vector sundir = vector "world" (.3, .6, .5);
    color suncolor = color(20, 18, 15);
    float sunsize = .9995, glow = 64;
    float cloudcover = .3;)
{
    vector D = normalize(vtransform("world", I));
    vector up = normalize(vector "world" (0, 1, 0));
    vector sunw = normalize(vtransform("world", sundir));
    float elev = D . up;

    color sky = mix(horizoncolor, zenithcolor, pow(max(elev, 0), .5));
    color C = (elev >= 0) ? sky : mix(horizoncolor, groundcolor, smoothstep(0, .1, -elev));

    /* The sun: a hard disc plus an exponential glow around it. */
    float cosang = D . sunw;
    C += suncolor * smoothstep(sunsize, sunsize + .0002, cosang);
    C += .05 * suncolor * pow(max(cosang, 0), glow);

    /* Clouds on a plane high above the origin, seen from E. */
    if (elev > .02) {
        point Ew = transform("world", E);
        point onplane = Ew + D * ((1000 - ycomp(Ew)) / elev);
        float cl = smoothstep(1 - cloudcover, 1, .5 + .5 * fBm(onplane * .002, 4, 2, .5));
        C = mix(C, color(1, 1, 1), cl * smoothstep(.02, .2, elev));
    }

    Ci = C;
    Oi = 1;
}
