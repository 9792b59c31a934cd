/*
 * debug_messages.sl -- a diagnostic surface that reports what the renderer
 * knows about the object being shaded, once per grid of points near the
 * centre of the parameter space, and colours the object by name.
 *
 * Exercises: attribute("identifier:name"), option("Format") into a float
 * array, rendererinfo("renderer") and rendererinfo("version"),
 * textureinfo(), shadername(), format() with %s and %f, printf() with
 * %c %p %m, concat(),
 * match(), printf(), the stringifying SHOWFLOAT / SHOWPOINT macros from
 * config.h, token-pasting COMPONENT() (xcomp/ycomp), color "hsv" from a
 * hash of the name, uniform string and float array locals.
 */
#include "config.h"

surface debug_messages(
    string texname = "";
    float verbose = 1;)
{
    uniform string objname = "", renderer = "";
    uniform float fmt[3] = {0, 0, 1};
    uniform float version[4] = {0, 0, 0, 0};
    uniform float res[2] = {0, 0};
    uniform float hasname = attribute("identifier:name", objname);
    uniform float hasfmt = option("Format", fmt);
    uniform float hasren = rendererinfo("renderer", renderer);
    uniform float hasver = rendererinfo("version", version);
    uniform float hastex = 0;
    uniform string message = "";

    if (texname != "")
        hastex = textureinfo(texname, "resolution", res);

    message = format("%s on '%s' (%f x %f, aspect %f)", shadername(), objname,
                     fmt[0], fmt[1], fmt[2]);

    /* Report only at the parametric centre, to keep the log short. */
    if (verbose > 0 && abs(u - .5) < du && abs(v - .5) < dv) {
        printf("%s\n", message);
        if (hasren != 0 && hasver != 0)
            printf("renderer %s %f.%f\n", renderer, version[0], version[1]);
        if (hastex != 0)
            printf("%s\n", concat("texture ", texname, format(" is %f x %f", res[0], res[1])));
        printf("Cs=%c P=%p world=%m\n", Cs, P, matrix "world" 1);
        SHOWFLOAT(COMPONENT(x, P));
        SHOWFLOAT(COMPONENT(y, P));
        SHOWPOINT(transform("world", P));
    }

    /* Objects whose names start with "debug" glow red; others get a hue. */
    color C;
    if (hasname != 0 && match("^debug", objname) != 0)
        C = color(1, 0, 0);
    else
        C = color "hsv" (mod(hasfmt * .37 + hasname * .11, 1), .5, 1);

    normal Nf = faceforward(normalize(N), I);
    Oi = Os;
    Ci = Os * C * (.2 + .8 * diffuse(Nf));
}
