/*
 * slide_projector.sl -- projects a slide (texture map) from the light's
 * position along its axis, with a shadow map, like a slide projector or
 * a gobo on a stage light.
 *
 * Exercises: illuminate(from, axis, angle), transform() of Ps into
 * "shader" space to find slide coordinates, texture() of a colour map
 * with "blur" and of a single channel ("name"[1]), shadow(), tan() and
 * radians() for the projection field, vector space casts, the format()
 * call with %p and %f, printf(), and a uniform debug switch.
 */
light slide_projector(
    float intensity = 1;
    float fieldofview = 30;
    point from = point "shader" (0, 0, 0);
    vector axis = vector "shader" (0, 0, 1);
    string slidename = "";
    string shadowname = "";
    float slideblur = 0;
    float debug = 0;)
{
    uniform float halfangle = radians(fieldofview) / 2;
    uniform float spread = 1 / tan(halfangle);
    uniform string where = format("projector at %p, fov %f", from, fieldofview);

    if (debug > 0)
        printf("%s\n", where);

    illuminate(from, axis, halfangle * 1.5) {
        point Pl = transform("shader", Ps);
        float x = xcomp(Pl), y = ycomp(Pl), z = max(zcomp(Pl), 1.0e-4);

        /* Slide coordinates in [0, 1], only in front of the projector. */
        float ss = .5 + .5 * spread * x / z;
        float tt = .5 - .5 * spread * y / z;
        color slide = 0;
        if (zcomp(Pl) > 0 && ss >= 0 && ss <= 1 && tt >= 0 && tt <= 1) {
            if (slidename != "") {
                slide = color texture(slidename, ss, tt, "blur", slideblur);
                slide *= .5 + .5 * float texture(slidename[1], ss, tt);
            } else {
                slide = 1;
            }
        }

        float lit = 1;
        if (shadowname != "")
            lit = 1 - shadow(shadowname, Ps);

        Cl = intensity * slide * lit / (L . L);
    }
}
