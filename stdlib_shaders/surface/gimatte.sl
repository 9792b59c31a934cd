/*
 * gimatte.sl -- a diffuse surface lit directly and indirectly (global illumination).
 *
 * Reflectance Cs * Kd, physically normalised: the radiance it reflects is its reflectance over
 * pi times the irradiance, direct (diffuse(), from the scene's lights), caustic (photonmap() of
 * the frame's caustic photons, with Option "gi" "causticphotons") and indirect
 * (indirectdiffuse(): the mean radiance arriving over the hemisphere, which is irradiance over
 * pi already). With Option "gi" "virtuallights" set, the indirect light comes from the frame's
 * virtual point lights (instant radiosity, docs/global_illumination.md); otherwise from
 * `samples` rays over the hemisphere.
 *
 * Parameters:
 *   Kd      -- scale applied to the reflectance Cs (1). Light paths see Cs alone.
 *   samples -- hemisphere rays per point when virtual lights are off (16);
 *              where the application lowers the ray parameter "relevance"
 *              below 1 (docs/ray_parameters.md), samples * relevance (at
 *              least 1).
 *
 * Outputs (for the "interleavefilter" pixel shader, which smooths the
 * indirect light alone with them):
 *   indirect       -- what indirectdiffuse() returned: the indirect light.
 *   indirectweight -- what Ci weighs it by (Os * Cs * Kd).
 */
surface gimatte(float Kd = 1; float samples = 16;
                output varying color indirect = 0; output varying color indirectweight = 0;)
{
    normal Nf = faceforward(normalize(N), I);
    uniform float relevance = 1;

    rayinfo("relevance", relevance);

    Oi = Os;
    color caustic = photonmap("caustic", P, Nf);
    indirectweight = Os * Cs * Kd;
    indirect = indirectdiffuse(P, Nf, max(1, ceil(samples * relevance)));
    Ci = indirectweight * ((diffuse(Nf) + caustic) / PI + indirect);
}
