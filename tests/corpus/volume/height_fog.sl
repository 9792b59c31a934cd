/*
 * height_fog.sl -- exponential height fog: density falls off
 * exponentially with altitude, and the optical depth along the ray is
 * integrated in closed form, so there is no marching.
 *
 * Exercises: transform() and vtransform() to "world", the analytic
 * integral of exp(-k y) along a ray (with a branch for horizontal rays),
 * abs(), exp(), ?:, mix() on Ci/Oi, and a point "world" space cast.
 */
volume height_fog(
    float basedensity = .2;
    float falloff = .5;
    float baseheight = 0;
    color fogcolor = color(.75, .78, .82);)
{
    point Pw = transform("world", P);
    vector Iw = vtransform("world", I);
    point Ew = Pw - Iw;
    float y0 = ycomp(Ew) - baseheight, y1 = ycomp(Pw) - baseheight;
    float dy = y1 - y0;
    float len = length(Iw);

    /* Integral of basedensity * exp(-falloff * y) along the segment. */
    float tau = (abs(dy) > 1.0e-4)
                ? basedensity * len * (exp(-falloff * y0) - exp(-falloff * y1)) / (falloff * dy)
                : basedensity * len * exp(-falloff * y0);

    /* No fog beyond a large radius around the world origin (outside the set). */
    float inset = (distance(P, point "world" (0, 0, 0)) > 1e5) ? 0 : 1;
    float amount = (1 - exp(-max(tau, 0))) * inset;

    Ci = mix(Ci, fogcolor, amount);
    Oi = mix(Oi, color(1, 1, 1), amount);
}
