/*
 * cylindrical.sl -- rtsl's standard camera shaders: "cylindrical".
 *
 * A panorama: the image's width spans `hfov` degrees around the camera's
 * vertical axis (360 is the full circle), and each column is a perspective
 * view in height, spanning `vfov` degrees across the image's height, as on
 * the inside of a cylinder.
 *
 * Parameters:
 *   hfov -- horizontal angle across the image's width, degrees (360).
 *   vfov -- vertical angle across the image's height, degrees (90).
 */
camera cylindrical(float hfov = 360; float vfov = 90;)
{
    uniform float format[3] = {640, 480, 1};
    option("Format", format);
    /* s spans [-aspect, aspect] when the image is wider than high, else [-1, 1]. */
    uniform float smax = max(format[0] / format[1], 1);
    uniform float tmax = max(format[1] / format[0], 1);
    float phi = (s / smax) * radians(hfov) / 2;
    float y = (t / tmax) * tan(radians(vfov) / 2);
    E = point "camera" (0, 0, 0);
    I = vector "camera" (sin(phi), y, cos(phi));
    Ci = 1;
}
