/*
 * glow_halo.sl -- a glow placed on a transparent sphere around a light
 * bulb: brightest where the view ray passes through the centre, fading
 * towards the silhouette, and invisible from inside.
 *
 * Exercises: the dot product operator on I and N, squared lengths via
 * (v . v), pow() falloff, if/else on a varying condition assigning Ci and
 * Oi in both branches, depth() to dim distant glows, and a shader with
 * no lighting calls at all.
 */
surface glow_halo(
    float attenuation = 2;
    float intensity = 1;
    float depthfade = 0;
    color glowcolor = color(1, .85, .5);)
{
    float falloff = I . N;

    if (falloff < 0) {
        /* cos^2 of the angle between the eye ray and the normal. */
        falloff = (falloff * falloff) / ((I . I) * (N . N));
        falloff = pow(falloff, attenuation);
        falloff *= 1 - depthfade * depth(P);
        Ci = intensity * glowcolor * falloff;
        Oi = falloff;
    } else {
        Ci = 0;
        Oi = 0;
    }
}
