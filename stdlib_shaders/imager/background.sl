/*
 * background.sl -- RenderMan Interface Specification 3.2, Appendix A
 * (standard imager shaders): "background".
 *
 * Composites the rendered pixel over a constant background colour: where
 * the pixel is partly transparent (alpha < 1) the background shows through
 * in proportion, and the result is made fully opaque.
 *
 * Parameters:
 *   background -- the colour behind the scene (1, white).
 *   bgcolor    -- multiplies it: the name BMRT's and Aqsis's background
 *                 imagers give the colour, so their scenes set it (1).
 */
imager background(color background = 1; color bgcolor = 1;)
{
    Ci += (1 - alpha) * bgcolor * background;
    Oi = 1;
    alpha = 1;
}
