/*
 * envbackground.sl -- an environment map behind the scene.
 *
 * Composites the rendered pixel over what an environment map shows along the pixel's camera
 * ray (a pinhole's: the image's shorter side spans the camera's field of view, as rtsl's
 * perspective camera frames it), and makes it opaque. A VRML Background's sky, ground and
 * panorama are such a map (docs/vrml.md).
 *
 * Parameters:
 *   envname    -- a latitude-longitude environment map ("" shows the background colour)
 *   background -- the colour where there is no map (0, black).
 */
imager envbackground(string envname = ""; color background = 0;)
{
    uniform float format[3] = {1, 1, 1};
    uniform float fov = 90;
    option("Format", format);
    option("FieldOfView", fov);
    float side = min(format[0], format[1]);
    float k = tan(radians(fov) / 2);
    vector dir = vector((2 * xcomp(P) - format[0]) / side * k, (format[1] - 2 * ycomp(P)) / side * k, 1);
    color seen = background;
    if (envname != "") {
        seen = color environment(envname, vtransform("camera", "world", dir));
    }
    Ci += (1 - alpha) * seen;
    Oi = 1;
    alpha = 1;
}
