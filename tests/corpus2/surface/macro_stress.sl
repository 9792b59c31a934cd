/*
 * macro_stress.sl -- a three-layer "painted tin" surface written the way
 * preprocessor-happy production shaders were: parameters declared by a
 * token-pasting macro, layers composited by statement macros, a light
 * loop that comes from a macro, and quality switches on numeric macros.
 *
 * Exercises: a header included three times (twice directly, once via
 * shade_models.h) behind its guard; LAYER_PARAMS(n, ...) with a macro
 * argument containing commas inside parentheses, used in the shader
 * parameter list; SWAP/SORT3 statement macros followed by ';'; nested
 * expression macros (GAIN -> BIAS); a self-referential macro that
 * wraps a built-in of the same name (cpp does not re-expand it);
 * #if 0 blocks; #if/#elif on SHADING_QUALITY set before the include;
 * #ifdef/#ifndef toggles; #undef then redefinition; __LINE__ and
 * __FILE__; a multi-line macro with backslashes that declares locals;
 * and token pasting that builds variable names.
 */
#define SHADING_QUALITY 3
#include "macros_util.h"
#include "shade_models.h"
#include "macros_util.h"

/* Wrap a built-in with a macro of the same name: the inner call is not re-expanded. */
#define ambient() (ambient() * ambientscale)

#define LAYERVAR(name, n) name##_##n

/* Composite one layer on top of Ct where its mask is on. */
#define COMPOSITE_LAYER(n, mask) \
    float LAYERVAR(m, n) = clamp(mask, 0, 1); \
    Ct = mix(Ct, LAYERVAR(color, n) * LAYERVAR(Kd, n), LAYERVAR(m, n)); \
    coverage = max(coverage, LAYERVAR(m, n))

#if 0
    This is not shader code: a disabled block must be skipped entirely,
    even with an unbalanced ( parenthesis or a stray " quote.
#endif

surface macro_stress(
    float Ka = 1, Kd = 0.8, Ks = 0.3, roughness = 0.15;
    float ambientscale = 0.5;
    LAYER_PARAMS(1, color(0.8, 0.2, 0.1));
    LAYER_PARAMS(2, color(0.9, 0.8, 0.2));
    LAYER_PARAMS(3, color(0.1, 0.3, 0.7));
    float contrast = 0.7;
    float debug = 0;)
{
    color Ct = Cs;
    float coverage = 0;
    float a = noise(s * freq_1, t * freq_1);
    float b = noise(s * freq_2 + 3.1, t * freq_2);
    float c = noise(s * freq_3 + 7.7, t * freq_3 - 1.2);

    /* Sort the three noise values so the layers nest (SORT3 -> SORT2 -> SWAP). */
    SORT3(a, b, c);

#if NOCTAVES >= 8
    /* Extra detail at high quality. */
    uniform float oct;
    float detail = 0;
    for (oct = 0; oct < NOCTAVES; oct += 1)
        detail += pow(0.5, oct) * (2 * noise(s * 20 * pow(2, oct), t * 20 * pow(2, oct)) - 1);
#elif NOCTAVES >= 4
    float detail = 2 * noise(s * 20, t * 20) - 1;
#else
    float detail = 0;
#endif

    COMPOSITE_LAYER(1, GAIN(contrast, a) * 2 - 0.5 + 0.1 * detail);
    COMPOSITE_LAYER(2, GAIN(contrast, b) * 2 - 0.8);
    COMPOSITE_LAYER(3, smoothstep(0.6, 0.65, c + 0.05 * detail));

    /* Swap two colours of a layer pair when asked to, via the colour SWAP. */
    color lo = color_1, hi = color_3;
    if (LUMA(lo) > LUMA(hi))
        SWAPC(lo, hi);
    Ct = mix(Ct, mix(lo, hi, coverage), 0.1);

    normal Nf = faceforward(normalize(N), I);
    vector V = -normalize(I);
    color diff = 0;
    ACCUM_DIFFUSE(diff, P, Nf)

#undef SPECFUNC
#define SPECFUNC(n, v, r) specular_msg(n, v, r)
    color spec = SPECFUNC(Nf, V, roughness);

#ifndef NO_DEBUG_PRINTS
    if (debug != 0) {
        printf("%s:%d ", __FILE__, __LINE__);
        TRACEVAL("%f\n", coverage)
    }
#endif

    Oi = Os;
    Ci = Os * (Ct * (Ka * ambient() + Kd * diff) + Ks * spec * (1 - 0.5 * coverage));
}
