/*
 * water_surface.sl -- the surface of a lake: wind ripples perturb the
 * normal, the sky is reflected, and the refracted view into the water is
 * darkened by murk whose density comes from the interior volume shader.
 *
 * Exercises: vector-valued noise (vfBm from noises.h) for normal
 * perturbation, fresnel() with five arguments, reflect() and refract(),
 * trace() and environment(), incident() and opposite() to read the
 * volume shaders on either side, atmosphere() to read the fog shader,
 * transform() to "world", time-animated noise, && conditions, and mix()
 * of colours.
 */
#include "noises.h"

surface water_surface(
    float Kr = 1, Kt = .8, Ks = 1, roughness = .01;
    float eta = 1.33;
    float ripplefreq = 3, rippleheight = .15, windspeed = .4;
    string envname = "";
    color deepcolor = color(.02, .08, .1);)
{
    point Pw = transform("world", P);
    point Pr = Pw * ripplefreq + vector(windspeed * time, 0, .3 * time);
    vector ripple = rippleheight * vfBm(Pr, 4, 2, .5);
    normal Nn = normalize(normalize(N) + vtransform("world", "current", ripple));
    normal Nf = faceforward(Nn, I);
    vector In = normalize(I);
    vector V = -In;
    float kr, kt;

    fresnel(In, Nf, 1 / eta, kr, kt);
    vector R = reflect(In, Nf);
    vector T = refract(In, Nf, 1 / eta);

    /* Sky: environment map if named, traced otherwise. */
    color sky = (envname != "") ? color environment(envname, vtransform("world", R))
                                : trace(P, R);

    /* Murk: densities of the water volume (opposite) and the air (incident). */
    float murk = .5, airfog = 0, fogdens = 0;
    opposite("murk", murk);
    incident("density", airfog);
    atmosphere("density", fogdens);
    color under = trace(P, T);
    under = mix(under, deepcolor, clamp(murk, 0, 1));
    if (airfog > 0 && fogdens > 0)
        sky *= 1 - .5 * clamp(airfog * fogdens, 0, 1);

    Oi = 1;
    Ci = Kr * kr * sky + Kt * kt * under + Ks * specular(Nf, V, roughness);
}
