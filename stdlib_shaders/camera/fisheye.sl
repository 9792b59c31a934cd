/*
 * fisheye.sl -- rtsl's standard camera shaders: "fisheye".
 *
 * An equidistant ("f-theta") fisheye lens: the angle from the optical axis
 * grows linearly with the distance from the image centre.  A circular
 * fisheye (fit "circle") covers `fov` degrees over the circle inscribed in
 * the image (180 is a hemisphere; more sees behind the camera), and makes no
 * ray outside the circle.  A full-frame fisheye (fit "diagonal") covers `fov`
 * degrees over the image's diagonal, corner to corner, so every pixel sees.
 *
 * Parameters:
 *   fov -- the angle the circle or the diagonal covers, in degrees (180).
 *   fit -- "circle" or "diagonal" (anything else counts as "circle").
 */
camera fisheye(float fov = 180; string fit = "circle";)
{
    /* s and t span [-1, 1] across the image's shorter side: the corners lie at
     * the half diagonal. */
    uniform float format[3] = {1, 1, 1};
    option("Format", format);
    uniform float aspect = max(format[0], format[1]) / max(1, min(format[0], format[1]));
    uniform float rim = (fit == "diagonal") ? sqrt(1 + aspect * aspect) : 1;
    /* The angle per unit of r, worked out once. */
    uniform float scale = radians(fov) / (2 * rim);
    float r = sqrt(s * s + t * t);
    float theta = r * scale;
    /* (s, t) / r is the cosine and sine of the angle around the optical axis, so the direction
     * needs no atan, and no sin and cos of it; at the centre s and t are 0 and any factor will do. */
    float k = (r > 0) ? sin(theta) / r : 0;
    E = point "camera" (0, 0, 0);
    I = vector "camera" (k * s, k * t, cos(theta));
    Ci = (r <= rim) ? 1 : 0;
}
