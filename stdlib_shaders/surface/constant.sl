/*
 * constant.sl -- RenderMan Interface Specification 3.2, Appendix A (standard
 * surface shaders): "constant".
 *
 * The simplest surface: the object is flat-shaded with its own colour and
 * opacity, with no lighting at all.  The result is the surface colour Cs
 * premultiplied by the surface opacity Os.
 *
 * Parameters: none.
 */
surface constant()
{
    Oi = Os;
    Ci = Os * Cs;
}
