/*
 * matte.sl -- RenderMan Interface Specification 3.2, Appendix A (standard
 * surface shaders): "matte".
 *
 * A purely diffuse (Lambertian) surface lit by the ambient and the
 * non-ambient light sources of the scene.  The shading normal is turned to
 * face the viewer so two-sided surfaces light correctly.
 *
 * Parameters:
 *   Ka  -- scale applied to the ambient light reaching the surface (1).
 *   Kd  -- scale applied to the diffuse reflection (1).
 */
surface matte(float Ka = 1; float Kd = 1;)
{
    normal Nf = faceforward(normalize(N), I);

    Oi = Os;
    Ci = Os * Cs * (Ka * ambient() + Kd * diffuse(Nf));
}
