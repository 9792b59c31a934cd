/*
 * fog.sl -- RenderMan Interface Specification 3.2, Appendix A (standard
 * volume shaders): "fog".
 *
 * Exponential fog: the colour of each point is blended towards the
 * background colour by 1 - exp(-length(I) / distance), where length(I) is
 * the distance the ray travelled to reach the point.  Light travelling
 * "distance" units keeps 1/e of its original colour.
 *
 * Parameters:
 *   distance   -- the e-folding distance of the fog (1).
 *   background -- the colour of the fog (0, black).
 */
volume fog(float distance = 1; color background = 0;)
{
    float d;

    d = 1 - exp(-length(I) / distance);
    Ci = mix(Ci, background, d);
    Oi = mix(Oi, color(1, 1, 1), d);
}
