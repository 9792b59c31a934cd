/*
 * gamma.sl -- rtsl's standard pixel shaders: "gamma".
 *
 * Encodes the linear colour for display.  With srgb on (the default) it
 * applies the sRGB transfer curve (linear below 0.0031308, a 1/2.4 power
 * above), otherwise a plain power 1/gamma.  Negative values are clamped
 * to 0 first.  The curve is applied to Ci as it is (premultiplied), which
 * is right wherever alpha is 0 or 1.  rtsl's 8-bit images and viewer are
 * sRGB-encoded already: this shader is for outputs written linear
 * (rtsl render --transfer linear, or EXR meant for display as it is).
 *
 * Parameters:
 *   gamma -- display gamma when srgb is off (2.2).
 *   srgb  -- 1 for the sRGB curve, 0 for the power law (1).
 */
float encode(float x; float g; float srgb;)
{
    float c = max(x, 0);
    float r;
    if (srgb != 0)
        r = c <= 0.0031308 ? 12.92 * c : 1.055 * pow(c, 1 / 2.4) - 0.055;
    else
        r = pow(c, 1 / g);
    return r;
}

pixel gamma(float gamma = 2.2; float srgb = 1;)
{
    Ci = color(encode(comp(Ci, 0), gamma, srgb),
               encode(comp(Ci, 1), gamma, srgb),
               encode(comp(Ci, 2), gamma, srgb));
}
