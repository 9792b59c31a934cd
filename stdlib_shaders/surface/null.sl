/*
 * null.sl -- RenderMan Interface Specification 3.2, Appendix A: the null
 * shader, "a placeholder if no action is to be performed".
 *
 * As a surface it sets nothing, so Ci and Oi keep the values they start
 * with: black and opaque.  For the other shader types the RIB reader takes
 * the name "null" to mean no shader at all (no displacement, atmosphere,
 * interior, exterior or imager; no light).
 *
 * Parameters: none.
 */
surface null()
{
}
