/*
 * ambientlight.sl -- RenderMan Interface Specification 3.2, Appendix A
 * (standard light source shaders): "ambientlight".
 *
 * Non-directional ambient light.  Because it sets Cl without an
 * illuminate() or solar() statement, the light contributes only to the
 * ambient() term of surface shaders, never to diffuse() or specular().
 *
 * Parameters:
 *   intensity  -- brightness of the light (1).
 *   lightcolor -- colour of the light (1, white).
 */
light ambientlight(float intensity = 1; color lightcolor = 1;)
{
    Cl = intensity * lightcolor;
}
