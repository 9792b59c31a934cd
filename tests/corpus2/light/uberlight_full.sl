/*
 * uberlight_full.sl -- a large "uber" light in the spirit of Barzel's
 * lighting-controls paper: spot/omni/parallel modes, cut-on and cut-off
 * distances with soft edges, a falloff that is capped near the light,
 * a superelliptical cross-section with shear, four barn doors, a slide
 * and a noise gobo, two shadow maps by name with blur/samples/bias, and
 * the full set of message-passing outputs.
 *
 * Exercises: a long parameter list with grouped declarations,
 * uniform string comparisons choosing between illuminate(from, axis,
 * angle), illuminate(from) and solar(axis, angle), helper functions with
 * many parameters called inside light blocks, transform("shader", Ps),
 * shadow() with "blur"/"samples"/"bias", texture() on a slide,
 * noise() on a shifted point, writing output varying parameters
 * (__unshadowed_Cl, __shadowfraction) from inside illuminate, uniform
 * locals computed from parameters, and the __category /
 * __nonspecular / __nondiffuse / __foglight conventions.
 */

#define EPS 1.0e-6

/* Soft clip in depth: zero before cuton, one after it, zero past cutoff. */
float clip_and_fade(float z, cuton, cutoff, nearedge, faredge)
{
    float nearfade = (nearedge > 0) ? smoothstep(cuton - nearedge, cuton, z) : step(cuton, z);
    float farfade = (faredge > 0) ? 1 - smoothstep(cutoff, cutoff + faredge, z)
                                  : 1 - step(cutoff, z);
    return nearfade * farfade;
}

/* Distance falloff 1/d^k, smoothly capped at maxintensity close to the light. */
float capped_falloff(float d, falloff, falloffdist, maxintensity)
{
    float atten = 1;
    if (falloff != 0) {
        if (d > falloffdist || maxintensity <= 1) {
            atten = pow(falloffdist / max(d, EPS), falloff);
        } else {
            float ls = log(maxintensity);
            float beta = -falloff / ls;
            atten = maxintensity * exp(ls * pow(d / falloffdist, beta));
        }
    }
    return atten;
}

/* Superellipse distance: 1 on the boundary, below 1 inside. */
float superdist(float x, y, a, b, roundness)
{
    float d;
    if (roundness < 0.01) {
        d = max(abs(x) / a, abs(y) / b);
    } else {
        float e = 2 / roundness;
        d = pow(pow(abs(x) / a, e) + pow(abs(y) / b, e), roundness / 2);
    }
    return d;
}

/* Cross-section shaping: 1 inside (width, height), fading to 0 over the edges. */
float crosssection(float x, y, width, height, wedge, hedge, roundness)
{
    float inner = superdist(x, y, width, height, roundness);
    float outer = superdist(x, y, width + wedge, height + hedge, roundness);
    /* Fraction of the way from the inner boundary to the outer one. */
    float frac = (inner - 1) / max(inner - outer, EPS);
    return (inner <= 1) ? 1 : ((outer >= 1) ? 0 : 1 - smoothstep(0, 1, frac));
}

/* Four barn doors given as slopes in the light's projected plane. */
float barndoors(float x, y, left, right, top, bottom, edge)
{
    return smoothstep(left - edge, left, x) * (1 - smoothstep(right, right + edge, x))
         * smoothstep(bottom - edge, bottom, y) * (1 - smoothstep(top, top + edge, y));
}

light uberlight_full(
    /* Type and colour */
    uniform string lighttype = "spot";       /* "spot", "omni" or "parallel" */
    float intensity = 1;
    color lightcolor = 1;
    /* Distance shaping */
    float cuton = 0.01, cutoff = 1.0e6, nearedge = 0, faredge = 0;
    float falloff = 0, falloffdist = 1, maxintensity = 1;
    /* Cross-section shaping */
    float parallelrays = 0;
    float shearx = 0, sheary = 0;
    float width = 1, height = 1, wedge = 0.1, hedge = 0.1;
    float roundness = 1;
    float beamdistribution = 0;
    /* Barn doors */
    float barnleft = -1.0e6, barnright = 1.0e6, barntop = 1.0e6, barnbottom = -1.0e6;
    float barnedge = 0.02;
    /* Cookies */
    string slidename = "";
    float noiseamp = 0, noisefreq = 4;
    vector noiseoffset = 0;
    /* Shadows */
    string shadowmap = "", shadowmap2 = "";
    float shadowblur = 0.01, shadowbias = 0.01, shadowsamples = 16;
    float shadowdensity = 1;
    color shadowcolor = 0;
    /* Message passing */
    uniform string __category = "uberlight,key";
    output uniform float __nonspecular = 0;
    output uniform float __nondiffuse = 0;
    output uniform float __foglight = 1;
    output varying float __shadowfraction = 0;
    output varying color __unshadowed_Cl = 0;)
{
    uniform point origin = point "shader" (0, 0, 0);
    uniform vector axis = normalize(vector "shader" (0, 0, 1));
    uniform float maxradius = 1.4142136 *
        max(height + hedge + abs(sheary), width + wedge + abs(shearx));
    uniform float coneangle = atan(maxradius);
    color unshad = 0;
    float shad = 0;

    /* The three modes share the shaping code through this macro. */
#define UBER_SHAPE(dist) \
    point PL = transform("shader", Ps); \
    float z = max(zcomp(PL), EPS); \
    float x = mix(xcomp(PL) / z, xcomp(PL), parallelrays) - shearx; \
    float y = mix(ycomp(PL) / z, ycomp(PL), parallelrays) - sheary; \
    float atten = clip_and_fade(z, cuton, cutoff, nearedge, faredge) \
                * capped_falloff(dist, falloff, falloffdist, maxintensity) \
                * crosssection(x, y, width, height, wedge, hedge, roundness) \
                * barndoors(x, y, barnleft, barnright, barntop, barnbottom, barnedge); \
    if (beamdistribution > 0) \
        atten *= pow(max(0, normalize(vector PL) . vector(0, 0, 1)), beamdistribution); \
    color lcol = lightcolor; \
    if (slidename != "") \
        lcol *= color texture(slidename, 0.5 + 0.5 * x / width, 0.5 - 0.5 * y / height); \
    if (noiseamp > 0) \
        atten *= clamp(1 + noiseamp * (2 * float noise(noisefreq * (point(x, y, 0) + noiseoffset)) - 1), 0, 1); \
    Cl = intensity * atten * lcol; \
    unshad = Cl; \
    if (shadowmap != "") \
        shad = shadow(shadowmap, Ps, "blur", shadowblur, "samples", shadowsamples, "bias", shadowbias); \
    if (shadowmap2 != "") \
        shad = max(shad, float shadow(shadowmap2, Ps, "blur", shadowblur, \
                                      "samples", shadowsamples, "bias", shadowbias)); \
    shad *= shadowdensity; \
    Cl = mix(Cl, Cl * shadowcolor, shad)

    if (lighttype == "omni") {
        illuminate(origin) {
            UBER_SHAPE(length(L));
        }
    } else if (lighttype == "parallel") {
        solar(axis, 0) {
            UBER_SHAPE(zcomp(transform("shader", Ps)));
        }
    } else {
        illuminate(origin, axis, coneangle) {
            UBER_SHAPE(length(L));
        }
    }
#undef UBER_SHAPE

    __shadowfraction = shad;
    __unshadowed_Cl = unshad;
}
