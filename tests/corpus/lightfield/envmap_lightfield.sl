/*
 * envmap_lightfield.sl -- radiance for escaping rays from an environment
 * map (cube or lat-long), rotated about the vertical axis, with a fallback
 * lat-long texture lookup and a constant colour when no map is named.
 *
 * Exercises: the "lightfield" shader type; environment() with "blur";
 * texture() with computed (s, t) from the direction, including the
 * "width" parameter; rotate() of an identity matrix built with a
 * "matrix 1" cast; vtransform() by a matrix; atan(), acos(), textureinfo()
 * with "type"; string comparison; a uniform string from concat(); and
 * the reading of u, v and s, t which lightfields receive.
 */
#include "config.h"

lightfield envmap_lightfield(
    string envname = "";
    string latlongname = "";
    float rotation = 0;
    float intensity = 1;
    float blur = 0;
    color fallback = color(.5, .5, .5);)
{
    matrix rot = rotate(matrix 1, radians(rotation), vector(0, 1, 0));
    vector D = normalize(vtransform(rot, vtransform("world", I)));
    uniform string maptype = "";
    uniform string which = concat("env:", envname, " latlong:", latlongname);
    color C = fallback;

    if (envname != "") {
        C = color environment(envname, D, "blur", blur);
    } else if (latlongname != "") {
        textureinfo(latlongname, "type", maptype);
        float ls = .5 + atan(xcomp(D), -zcomp(D)) / TWOPI;
        float lt = acos(clamp(ycomp(D), -1, 1)) / PI;
        C = color texture(latlongname, ls, lt, "width", (maptype == "texture") ? 1 : 0);
    }

    /* Lightfields also get the (s, t) and (u, v) of the ray's origin. */
    if (which == "env: latlong:")
        C *= .9 + .1 * (s + t + u + v) / 4;

    Ci = intensity * C;
    Oi = 1;
}
