/*
 * material.h -- reusable local illumination models and complete materials.
 *
 * Exercises: include guards, #include "config.h", functions that reach the
 * shader globals through extern declarations, custom illuminance loops
 * (illuminance(P, N, angle) and with a light-category string), the
 * lightsource("__nonspecular"/"__nondiffuse") message, dot products,
 * cross products, fresnel() with output arguments, and functions calling
 * other functions.
 */
#ifndef MATERIAL_H
#define MATERIAL_H

#include "config.h"

/* Lambertian reflection with ambient, like the "matte" shader. */
color MaterialMatte(normal Nf; color basecolor; float Ka, Kd)
{
    return basecolor * (Ka * ambient() + Kd * diffuse(Nf));
}

/* Diffuse base plus a white, uncoloured highlight, like "plastic". */
color MaterialPlastic(normal Nf; color basecolor; float Ka, Kd, Ks, roughness)
{
    extern vector I;
    return basecolor * (Ka * ambient() + Kd * diffuse(Nf))
           + Ks * specular(Nf, -normalize(I), roughness);
}

/* Metal: the highlight takes the base colour and there is no diffuse. */
color MaterialRoughMetal(normal Nf; color basecolor; float Ka, Ks, roughness)
{
    extern vector I;
    return basecolor * (Ka * ambient() + Ks * specular(Nf, -normalize(I), roughness));
}

/*
 * A diffuse loop that honours the __nondiffuse light parameter, so fill
 * lights can be kept out of it.
 */
color LocIllumDiffuse(normal Nn)
{
    extern point P;
    color C = 0;

    illuminance(P, Nn, HALFPI) {
        float nondiff = 0;
        lightsource("__nondiffuse", nondiff);
        C += Cl * (1 - nondiff) * (normalize(L) . Nn);
    }
    return C;
}

/*
 * Glossy highlight with a sharp edge ("sharpness" 0 gives a soft blob, 1 a
 * crisp disc), skipping lights that declare __nonspecular.
 */
color LocIllumGlossy(normal Nn; vector V; float roughness, sharpness)
{
    extern point P;
    color C = 0;
    float w = .18 * (1 - sharpness);

    illuminance(P, Nn, HALFPI) {
        float nonspec = 0;
        lightsource("__nonspecular", nonspec);
        if (nonspec < 1) {
            vector H = normalize(normalize(L) + V);
            C += Cl * (1 - nonspec)
                 * smoothstep(.72 - w, .72 + w, pow(max(0, Nn . H), 1 / roughness));
        }
    }
    return C;
}

/*
 * Oren-Nayar rough diffuse reflection; sigma is the standard deviation of
 * the facet slope angle, in radians.
 */
color LocIllumOrenNayar(normal Nn; vector V; float sigma)
{
    extern point P;
    float sig2 = SQR(sigma);
    float A = 1 - 0.5 * sig2 / (sig2 + 0.33);
    float B = 0.45 * sig2 / (sig2 + 0.09);
    float cos_r = clamp(V . Nn, 0, 1);
    float theta_r = acos(cos_r);
    vector Vperp = V - Nn * cos_r;
    color C = 0;

    if (length(Vperp) > 1.0e-4)
        Vperp = normalize(Vperp);

    illuminance(P, Nn, HALFPI) {
        vector Ln = normalize(L);
        float cos_i = Ln . Nn;
        float theta_i = acos(cos_i);
        vector Lperp = Ln - Nn * cos_i;
        float cos_phi = 0;
        if (length(Lperp) > 1.0e-4)
            cos_phi = Vperp . normalize(Lperp);
        float thmax = max(theta_i, theta_r);
        float thmin = min(theta_i, theta_r);
        C += Cl * cos_i * (A + B * max(0, cos_phi) * sin(thmax) * tan(thmin));
    }
    return C;
}

/*
 * Ward's anisotropic highlight.  xdir is the direction of the brushing;
 * xrough and yrough are the slope deviations along and across it.  Only
 * lights in the "specular" category (or with no category) take part.
 */
color LocIllumWardAnisotropic(normal Nn; vector V; vector xdir;
                              float xrough, yrough)
{
    extern point P;
    float cos_r = Nn . V;
    vector X = normalize(xdir);
    vector Y = Nn ^ X;
    color C = 0;

    if (cos_r > 0) {
        illuminance("specular", P, Nn, HALFPI) {
            vector Ln = normalize(L);
            float cos_i = Ln . Nn;
            if (cos_i > 0) {
                vector H = normalize(V + Ln);
                float hx = (H . X) / xrough;
                float hy = (H . Y) / yrough;
                float rho = exp(-2 * (SQR(hx) + SQR(hy)) / (1 + (H . Nn)))
                            / sqrt(cos_i * cos_r);
                C += Cl * cos_i * rho;
            }
        }
    }
    return C / (4 * xrough * yrough);
}

/*
 * A clear dielectric coat over a base colour: the coat reflects a
 * Fresnel-weighted fraction of the light and passes the rest down.
 */
color MaterialClearcoat(normal Nf; color base; float eta, coatrough)
{
    extern vector I;
    vector In = normalize(I);
    float Kr, Kt;

    fresnel(In, Nf, 1 / eta, Kr, Kt);
    return Kt * base + Kr * specular(Nf, -In, coatrough);
}

#endif /* MATERIAL_H */
