/*
 * fisheye.sl -- an equidistant ("f-theta") fisheye lens: the angle from
 * the optical axis grows linearly with distance from the image centre,
 * covering up to a full hemisphere or more.  Points outside the image
 * circle get zero weight.  A rolling-shutter option delays each row.
 *
 * Exercises: the "camera" shader type reading s, t, the raster position
 * P and time; option("Format") for the image height; sqrt(), atan(y, x),
 * sin(), cos(), radians(); vector "camera" casts; the ?: operator; the
 * rtsl camera output Ci as a weight.
 */
camera fisheye(
    float fov = 180;
    float rollingshutter = 0;
    vector motion = vector "camera" (0, 0, 0);)
{
    uniform float fmt[3] = {640, 480, 1};
    option("Format", fmt);

    float r = sqrt(s * s + t * t);
    float theta = r * radians(fov) / 2;
    float phi = atan(t, s);

    /* Each row of a rolling shutter is exposed a little later. */
    float rowtime = time + rollingshutter * ycomp(P) / fmt[1];

    E = point "camera" (0, 0, 0) + rowtime * motion;
    I = vector "camera" (sin(theta) * cos(phi), sin(theta) * sin(phi), cos(theta));
    Ci = (r <= 1) ? 1 : 0;
}
