/*
 * arealight.sl -- the area light of the RenderMan Interface Specification
 * 3.2 (RiAreaLightSource, and the illuminate() statement in Part II).
 *
 * An area light: the shader is attached to geometry (an AreaLightSource),
 * and for each sample the renderer sets P and N to a point on the emitting
 * surface and its normal there, and sums (averages, weighted by area) the
 * samples' contributions.  Each sample radiates into the hemisphere around
 * its normal (illuminate with a cone of PI/2) with inverse-square falloff.
 * As in the specification, no cosine of the emitter is applied: the
 * surface's own diffuse() supplies the receiver's cosine.  Unlike the
 * specification's version, a surface point at the sample itself (L = 0)
 * gets no light instead of an infinite one.
 *
 * Parameters:
 *   intensity  -- brightness of the light (1).
 *   lightcolor -- colour of the light (1, white).
 *   __nondiffuse, __nonspecular -- 1 leaves the light out of diffuse(),
 *                 and of specular() and phong() (RenderMan's convention; 0).
 */
light arealight(float intensity = 1; color lightcolor = 1;
                output float __nondiffuse = 0;
                output float __nonspecular = 0;)
{
    float d2;

    illuminate(P, N, PI / 2) {
        d2 = L . L;
        /* A point on the sample itself (L = 0) is not lit by it. */
        Cl = d2 > 0 ? (intensity / d2) * lightcolor : color 0;
    }
}
