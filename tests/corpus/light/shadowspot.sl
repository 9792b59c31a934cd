/*
 * shadowspot.sl -- a spotlight with a depth-map shadow, soft cone edges,
 * optional hard "pool" edge and a light category for selective lighting.
 *
 * Exercises: illuminate(from, axis, angle), shadow("name", Ps) with
 * optional "samples", "blur" and "bias" arguments, string parameters
 * compared with != "", uniform locals derived from parameters,
 * smoothstep cone falloff, pow() beam distribution, inverse-square
 * falloff via (L . L), the __category string parameter and the
 * __nonspecular output parameter, and color mix towards a shadow colour.
 */
light shadowspot(
    float intensity = 1;
    color lightcolor = 1;
    point from = point "shader" (0, 0, 0);
    point to = point "shader" (0, 0, 1);
    float coneangle = radians(30);
    float conedeltaangle = radians(5);
    float beamdistribution = 2;
    string shadowname = "";
    float samples = 16, blur = .005, bias = .01;
    color shadowcolor = 0;
    uniform string __category = "specular";
    output uniform float __nonspecular = 0;)
{
    uniform vector A = normalize(to - from);
    uniform float cosoutside = cos(coneangle);
    uniform float cosinside = cos(coneangle - conedeltaangle);
    uniform float haveshadow = (shadowname != "") ? 1 : 0;

    illuminate(from, A, coneangle) {
        float dist2 = L . L;
        float cosangle = (L . A) / sqrt(dist2);
        float atten = pow(cosangle, beamdistribution) / dist2;
        atten *= smoothstep(cosoutside, cosinside, cosangle);

        float unoccluded = 1;
        if (haveshadow > 0)
            unoccluded = 1 - shadow(shadowname, Ps, "samples", samples,
                                    "blur", blur, "bias", bias);

        Cl = atten * intensity * mix(shadowcolor, lightcolor, unoccluded);
    }
}
