/*
 * ridged_bumps.sl -- a "bumpy" variant for rocky or lava-like surfaces:
 * ridged multifractal noise gives sharp crests, and the bumped normal is
 * built by hand from the derivatives of the displaced position rather
 * than with calculatenormal().
 *
 * Exercises: ridged() from noises.h, NOISE_OCTAVES from the header's #if
 * logic, Du() and Dv() of a point and the cross product ^ to form a
 * normal, a dot-product orientation check against the original normal,
 * unary minus on a normal, mix(), pnoise() with a period so the pattern tiles in
 * (s, t), and the ?: operator.
 */
#include "noises.h"

displacement ridged_bumps(
    float Km = .05;
    float frequency = 3;
    float offset = 1, gain = .5;
    float tilesize = 4;
    float smoothness = 0;)
{
    point Psh = transform("shader", P) * frequency;
    normal Nn = normalize(N);

    float height = ridged(Psh, NOISE_OCTAVES, 2, gain, offset);

    /* Add a periodic layer in (s, t) that tiles every "tilesize" units. */
    height += .2 * pnoise(s * tilesize * 4, t * tilesize * 4, tilesize * 4, tilesize * 4);
    height = mix(height, .5, clamp(smoothness, 0, 1));

    point Pd = P + Km * height * Nn;

    /* Normal from the tangents of the displaced surface. */
    vector dPu = Du(Pd);
    vector dPv = Dv(Pd);
    normal Nd = normalize(dPu ^ dPv);
    Nd = ((Nd . Nn) < 0) ? -Nd : Nd;

    P = Pd;
    N = Nd;
}
