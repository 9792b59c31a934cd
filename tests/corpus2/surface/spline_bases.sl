/*
 * spline_bases.sl -- a test card: the surface is cut into horizontal
 * bands, each showing a colour ramp interpolated with a different
 * spline basis, plus a band whose basis is a string parameter and a
 * wavy float spline outline.
 *
 * Exercises: spline() with every RenderMan basis by name
 * ("catmull-rom", "bspline", "bezier", "hermite", "linear"), the
 * default (catmull-rom) basis with no name, spline over an array of
 * colours and over a float array, the basis given by a uniform string
 * parameter, point-valued spline through literal points, colour
 * arrays as locals initialised with {}, array element assignment,
 * floor() band selection and an if/else if chain on it.
 */
surface spline_bases(
    float Ka = 0.2, Kd = 0.8;
    uniform string userbasis = "catmull-rom";
    color ramp[7] = {color(0, 0, 0), color(0, 0, 0), color(0.9, 0.1, 0.1),
                     color(0.9, 0.9, 0.1), color(0.1, 0.6, 0.9),
                     color(1, 1, 1), color(1, 1, 1)};
    float heights[6] = {0, 0, 0.8, 0.3, 1, 1};)
{
    uniform float nbands = 7;
    float band = floor(t * nbands);
    float x = clamp(s, 0, 1);
    color Ct;

    /* Hermite wants value/tangent pairs: build them from the ramp. */
    color herm[6];
    herm[0] = ramp[2]; herm[1] = color(0);
    herm[2] = ramp[3]; herm[3] = ramp[4] - ramp[2];
    herm[4] = ramp[4]; herm[5] = color(0);

    /* Bezier: 3n+1 control values. */
    color bez[7] = {color(0.9, 0.1, 0.1), color(0.9, 0.5, 0.1), color(0.9, 0.9, 0.1),
                    color(0.5, 0.9, 0.5), color(0.1, 0.7, 0.9), color(0.5, 0.8, 1),
                    color(1, 1, 1)};

    if (band == 0)
        Ct = spline(x, ramp);
    else if (band == 1)
        Ct = spline("catmull-rom", x, ramp);
    else if (band == 2)
        Ct = spline("bspline", x, ramp);
    else if (band == 3)
        Ct = spline("bezier", x, bez);
    else if (band == 4)
        Ct = spline("hermite", x, herm);
    else if (band == 5)
        Ct = spline("linear", x, ramp[1], ramp[2], ramp[3], ramp[4], ramp[5]);
    else
        Ct = spline(userbasis, x, ramp);

    /* A float curve drawn as a dark line across each band. */
    float curve = spline("linear", x, heights);
    float wobble = spline(x, 0, 0, 0.1, -0.1, 0.05, 0, 0);
    float within = t * nbands - band;
    float line = 1 - smoothstep(0.01, 0.03, abs(within - curve - wobble));
    Ct = mix(Ct, color(0.05), line);

    /* Point spline: shift the band boundaries along a curved path. */
    point offs = spline("bspline", x, point(0, 0, 0), point(0, 0.02, 0),
                        point(0, -0.02, 0), point(0, 0.01, 0), point(0, 0, 0));
    float boundary = 1 - smoothstep(0, 0.01, abs(mod(t + ycomp(offs), 1 / nbands)));
    Ct *= 1 - 0.5 * boundary;

    normal Nf = faceforward(normalize(N), I);
    Oi = Os;
    Ci = Os * Ct * (Ka * ambient() + Kd * diffuse(Nf));
}
