/*
 * exposure.sl -- rtsl's standard pixel shaders: "exposure".
 *
 * A photographic exposure change: the pixel's colour is multiplied by
 * gain * 2^stops.  Coverage (alpha) is left as it is, and since Ci is
 * premultiplied by it, scaling Ci scales the unpremultiplied colour too.
 *
 * Parameters:
 *   stops -- exposure change in f-stops; +1 doubles the light (0).
 *   gain  -- a further linear factor (1).
 */
pixel exposure(float stops = 0; float gain = 1;)
{
    Ci *= gain * pow(2, stops);
}
