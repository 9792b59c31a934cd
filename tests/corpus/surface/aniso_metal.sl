/*
 * aniso_metal.sl -- brushed metal with an anisotropic (Ward) highlight;
 * brushing runs along the u direction of the surface or, optionally, in
 * circles around a centre (as on a machined disc).
 *
 * Exercises: dPdu as the tangent, the cross product operator ^ and
 * dot product . to build a frame, LocIllumWardAnisotropic (custom
 * illuminance loop with a "specular" category, in material.h),
 * vtransform() and ntransform() between named spaces, a nested function that reads shader locals through
 * extern, and ambient().
 */
#include "material.h"

surface aniso_metal(
    float Ka = 1, Ks = 1;
    float uroughness = .35, vroughness = .05;
    float circular = 0;
    point center = point "shader" (0, 0, 0);
    string brushspace = "shader";
    color metalcolor = color(.8, .8, .85);)
{
    normal Nn = normalize(N);
    normal Nf = faceforward(Nn, I);
    vector V = -normalize(I);
    vector tangent = normalize(dPdu);

    /* Circular brushing: the tangent goes around "center" in brushspace. */
    vector CircularTangent()
    {
        extern point P;
        extern normal Nf;
        extern point center;
        extern string brushspace;
        point Pb = transform(brushspace, P);
        point Cb = transform(brushspace, center);
        normal Nb = ntransform(brushspace, Nf);
        vector radial = Pb - Cb;
        vector around = Nb ^ radial;
        return normalize(vtransform(brushspace, "current", around));
    }

    if (circular > 0)
        tangent = normalize(mix(tangent, CircularTangent(), circular));

    /* Make the tangent exactly perpendicular to the normal. */
    tangent = normalize(tangent - (tangent . Nf) * Nf);

    color spec = LocIllumWardAnisotropic(Nf, V, tangent, uroughness, vroughness);

    Oi = Os;
    Ci = Os * metalcolor * (Ka * ambient() + Ks * spec);
}
