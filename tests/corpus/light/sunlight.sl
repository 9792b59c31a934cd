/*
 * sunlight.sl -- the sun and sky as one light: a directional sun whose
 * colour reddens as it nears the horizon, with ray-traced soft shadows,
 * plus a dim sky term from every direction.
 *
 * Exercises: solar(axis, angle) for the sun disc, solar() with no
 * arguments for the sky (two solar statements in one light), the
 * transmission() function toward a point far along -L, vector "world"
 * space casts, normalize(), color spline() with the "catmull-rom" basis,
 * the color "hsv" cast, radians(), and the __category parameter.
 */
light sunlight(
    float intensity = 3;
    float skyintensity = .3;
    vector sundir = vector "world" (0, -1, -.3);
    float sunangle = .53;
    float shadows = 1;
    float sunsamples = 4;
    uniform string __category = "specular";)
{
    uniform vector D = normalize(sundir);
    uniform float elevation = -(D . normalize(vector "world" (0, 1, 0)));
    uniform color suncolor = color spline("catmull-rom", clamp(elevation * 4, 0, 1),
                                          color(1, .3, .1), color(1, .3, .1),
                                          color(1, .7, .45), color(1, .95, .9),
                                          color(1, 1, 1), color(1, 1, 1));
    uniform color skycolor = color "hsv" (.6, .5, 1);

    solar(D, radians(sunangle)) {
        color vis = 1;
        if (shadows > 0)
            vis = transmission(Ps, Ps - 1000 * normalize(L), "samples", sunsamples);
        Cl = intensity * suncolor * vis;
    }

    solar() {
        Cl = skyintensity * skycolor * clamp(elevation + .2, 0, 1);
    }
}
