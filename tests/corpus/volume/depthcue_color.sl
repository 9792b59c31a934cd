/*
 * depthcue_color.sl -- aerial perspective: distant objects fade towards a
 * colour that itself changes with depth (warm haze near, cool sky far),
 * following a user curve.
 *
 * Exercises: depth(P), a colour spline with the "catmull-rom" basis and a
 * float spline with no basis, color "hsv" casts, clamp(), mix() on Ci
 * and Oi, ctransform() with one and two space names, comp() and
 * setcomp() on an HSV colour, and uniform locals computed from
 * parameters.
 */
volume depthcue_color(
    float mindistance = 0, maxdistance = 1;
    float nearhue = .08, farhue = .6;
    float saturation = .3;)
{
    uniform color nearhaze = color "hsv" (nearhue, saturation, 1);
    uniform color farhaze = color "hsv" (farhue, saturation, .9);
    float d = clamp((depth(P) - mindistance) / (maxdistance - mindistance), 0, 1);

    /* Haze amount along a gentle S-curve. */
    float amount = spline(d, 0, 0, .1, .5, .9, 1, 1);
    color haze = color spline("catmull-rom", d, nearhaze, nearhaze,
                              mix(nearhaze, farhaze, .5), farhaze, farhaze);

    /* Keep the haze's value no brighter than the object it covers (or .5). */
    color hsv = ctransform("hsv", haze);
    float objval = comp(ctransform("hsv", Ci), 2);
    setcomp(hsv, 2, min(comp(hsv, 2), max(objval, .5)));
    color hazefinal = ctransform("hsv", "rgb", hsv);

    Ci = mix(Ci, hazefinal, amount);
    Oi = mix(Oi, color(1, 1, 1), amount);
}
