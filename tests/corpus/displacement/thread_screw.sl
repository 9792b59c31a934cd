/*
 * thread_screw.sl -- screw threads on a cylinder whose t runs along the
 * axis and s around it: a helical sawtooth ridge, rounded at its crest,
 * fading out toward the tip of the screw.
 *
 * Exercises: mod() sawtooth, step() and smoothstep() shaping, spline()
 * with the "bspline" basis for the thread profile, the "hermite" basis for
 * the taper, P += on a displacement, calculatenormal(), a while loop that
 * refines an approximation, and user functions with several parameter
 * groups.
 */
/* Thread profile: height at position x in [0, 1) across one thread. */
float threadprofile(float x; float roundness)
{
    float tri = 1 - abs(2 * x - 1);
    float rounded = spline("bspline", tri, 0, 0, .5, 1, 1);
    return mix(tri, rounded, roundness);
}

/* Fixed-point iteration for the root of height(x) = target. */
float inverttaper(float target; float iterations)
{
    float x = target, k = 0;
    while (k < iterations) {
        x = x - (x * x * (3 - 2 * x) - target) / max(6 * x * (1 - x), .25);
        x = clamp(x, 0, 1);
        k += 1;
    }
    return x;
}

displacement thread_screw(
    float Km = .05;
    float threads = 20;
    float roundness = .6;
    float taperstart = .8;)
{
    /* Helix: position across the thread advances with s as we go around. */
    float x = mod(t * threads + s, 1);
    float h = threadprofile(x, roundness);

    /* Thread runs out over the tip of the screw. */
    float tip = step(taperstart, t) * (t - taperstart) / max(1 - taperstart, 1.0e-3);
    float taper = spline("hermite", clamp(tip, 0, 1), 1, 0, 0, 0);
    taper = inverttaper(clamp(taper, 0, 1), 4);

    P += Km * h * taper * normalize(N);
    N = calculatenormal(P);
}
