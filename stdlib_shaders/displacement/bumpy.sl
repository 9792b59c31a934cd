/*
 * bumpy.sl -- RenderMan Interface Specification 3.2, Appendix A (standard
 * displacement shaders): "bumpy".
 *
 * Displaces the surface along its normal by a height read from the first
 * channel of a texture map at (s, t), scaled by amplitude, then recomputes
 * the shading normal from the moved points.  When no map is named the
 * surface is left in place.  (The specification's version of this shader
 * calls the scale Km; this library names it amplitude.)
 *
 * Parameters:
 *   amplitude   -- height of a texture value of 1, in current space units (1).
 *   texturename -- name of the height texture; "" means none ("").
 */
displacement bumpy(float amplitude = 1; string texturename = "";)
{
    float amp = 0;

    if (texturename != "")
        amp = amplitude * float texture(texturename, s, t);

    P += amp * normalize(N);
    N = calculatenormal(P);
}
