/*
 * depthcue.sl -- RenderMan Interface Specification 3.2, Appendix A
 * (standard volume shaders): "depthcue".
 *
 * Atmospheric depth cueing: the colour of each point is blended linearly
 * towards the background colour according to its normalised depth between
 * mindistance and maxdistance (depth 0 at the near clipping plane, 1 at the
 * far one).  Points beyond maxdistance take the background colour and
 * become fully opaque.
 *
 * Parameters:
 *   mindistance -- normalised depth where the blend starts (0).
 *   maxdistance -- normalised depth where the blend is complete (1).
 *   background  -- colour the scene fades to (0, black).
 */
volume depthcue(float mindistance = 0; float maxdistance = 1;
                color background = 0;)
{
    float d;

    d = clamp((depth(P) - mindistance) / (maxdistance - mindistance), 0.0, 1.0);
    Ci = mix(Ci, background, d);
    Oi = mix(Oi, color(1, 1, 1), d);
}
