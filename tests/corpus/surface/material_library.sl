/*
 * material_library.sl -- one shader offering several illumination models,
 * chosen by name at render time, for look development.
 *
 * Exercises: every function of material.h (MaterialMatte, MaterialPlastic,
 * MaterialRoughMetal, LocIllumDiffuse, LocIllumGlossy, LocIllumOrenNayar,
 * MaterialClearcoat), string parameter comparison with == in an
 * if / else if chain, match() with a regular expression, concat(),
 * printf() of a string, the SHOWCOLOR stringification macro, a uniform
 * string local, and a float parameter used as a switch with !.
 */
#include "material.h"

surface material_library(
    string model = "plastic";
    float Ka = 1, Kd = .7, Ks = .4, roughness = .1;
    float sigma = .3, sharpness = .5, eta = 1.5;
    float verbose = 0;)
{
    normal Nf = faceforward(normalize(N), I);
    vector V = -normalize(I);
    color C;
    uniform string label = concat("material_library(", model, ")");

    if (model == "matte")
        C = MaterialMatte(Nf, Cs, Ka, Kd);
    else if (model == "metal")
        C = MaterialRoughMetal(Nf, Cs, Ka, Ks, roughness);
    else if (model == "orennayar")
        C = Cs * (Ka * ambient() + Kd * LocIllumOrenNayar(Nf, V, sigma));
    else if (match("^gloss", model) != 0)
        C = Cs * (Ka * ambient() + Kd * LocIllumDiffuse(Nf))
            + Ks * LocIllumGlossy(Nf, V, roughness, sharpness);
    else if (model == "clearcoat")
        C = MaterialClearcoat(Nf, MaterialMatte(Nf, Cs, Ka, Kd), eta, roughness);
    else
        C = MaterialPlastic(Nf, Cs, Ka, Kd, Ks, roughness);

    if (!(verbose == 0)) {
        printf("%s\n", label);
        SHOWCOLOR(C);
    }

    Oi = Os;
    Ci = Os * C;
}
