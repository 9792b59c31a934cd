/*
 * vrmlfog.sl -- VRML 97's Fog (ISO/IEC 14772-1, 6.19) as an atmosphere.
 *
 * Blends what the eye sees toward the fog colour with the distance d from the eye:
 * the fraction f of the surface's own colour that remains is
 *   (visibilityrange - d) / visibilityrange      (LINEAR)
 *   exp(-d / (visibilityrange - d))              (EXPONENTIAL)
 * and 0 from visibilityrange on; a visibilityrange of 0 disables the fog.
 *
 * Parameters:
 *   fogcolor        -- the colour of the fog (1, white).
 *   visibilityrange -- the distance at which everything is fog, in world units (0: no fog).
 *   exponential     -- 1 for VRML's EXPONENTIAL fog, 0 for LINEAR.
 */
volume vrmlfog(color fogcolor = 1; float visibilityrange = 0; float exponential = 0;)
{
    if (visibilityrange > 0) {
        float d = length(I);
        float f = 0;
        if (d < visibilityrange) {
            if (exponential != 0)
                f = exp(-d / (visibilityrange - d));
            else
                f = (visibilityrange - d) / visibilityrange;
        }
        Ci = f * Ci + (1 - f) * fogcolor;
        Oi = f * Oi + (1 - f);
    }
}
