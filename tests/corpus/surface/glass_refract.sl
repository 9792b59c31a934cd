/*
 * glass_refract.sl -- ray-traced glass: Fresnel-weighted reflection and
 * refraction, total internal reflection, and absorption by an interior
 * volume whose density is read from the volume shader through
 * incident()/opposite().
 *
 * Exercises: refract(), reflect(), fresnel() with five arguments,
 * trace() for both rays, raydepth() to stop recursion, the
 * incident() and opposite() message-passing calls, the (N . I) test for
 * entering vs. leaving, ?: on floats, exp() of a colour-valued product
 * built per channel, comp() and setcomp() on colours, uniform parameters.
 */
#include "config.h"

surface glass_refract(
    float Ka = 0, Ks = .8, Kr = 1, Kt = 1, roughness = .02;
    float eta = 1.5;
    uniform float maxdepth = 5;
    color absorption = color(.2, .05, .05);)
{
    normal Nn = normalize(N);
    vector In = normalize(I);
    normal Nf = faceforward(Nn, In);
    vector V = -In;
    float entering = ((In . Nn) < 0) ? 1 : 0;
    float ior = (entering > 0) ? 1 / eta : eta;
    float kr, kt;
    vector R, T;

    fresnel(In, Nf, ior, kr, kt);
    R = normalize(reflect(In, Nf));
    T = refract(In, Nf, ior);

    /* Density of the medium on each side, if volume shaders provide it. */
    float dens_in = 1, dens_out = 0;
    incident("density", dens_out);
    opposite("density", dens_in);

    color Crefl = 0, Crefr = 0;
    if (raydepth() < maxdepth) {
        Crefl = trace(P, R);
        if (kt > 0 && length(T) > 0) {
            Crefr = trace(P, T);
        } else {
            /* Total internal reflection: everything goes to reflection. */
            kr = 1;
        }
    }

    /* Leaving the glass: attenuate by Beer's law over the path length. */
    if (entering == 0) {
        float pathlen = length(I) * dens_in;
        color att = 1;
        setcomp(att, 0, exp(-comp(absorption, 0) * pathlen));
        setcomp(att, 1, exp(-comp(absorption, 1) * pathlen));
        setcomp(att, 2, exp(-comp(absorption, 2) * pathlen));
        Crefr *= att;
    }
    Crefr *= 1 - clamp(dens_out, 0, 1) * .1;

    Oi = 1;
    Ci = Ka * ambient() + Ks * specular(Nf, V, roughness)
         + Kr * kr * Crefl + Kt * kt * Crefr;
}
