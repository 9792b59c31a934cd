/*
 * fisheye.sl -- rtsl's standard camera shaders: "fisheye".
 *
 * An equidistant ("f-theta") fisheye lens: the angle from the optical axis
 * grows linearly with the distance from the image centre, so the circle
 * inscribed in the image covers `fov` degrees (180 is a hemisphere; more
 * sees behind the camera).  Outside the circle the camera makes no ray.
 *
 * Parameters:
 *   fov -- the angle the inscribed circle covers, in degrees (180).
 */
camera fisheye(float fov = 180;)
{
    float r = sqrt(s * s + t * t);
    float theta = r * radians(fov) / 2;
    /* (s, t) / r is the cosine and sine of the angle around the optical axis, so the direction
     * needs no atan, and no sin and cos of it; at the centre s and t are 0 and any factor will do. */
    float k = (r > 0) ? sin(theta) / r : 0;
    E = point "camera" (0, 0, 0);
    I = vector "camera" (k * s, k * t, cos(theta));
    Ci = (r <= 1) ? 1 : 0;
}
