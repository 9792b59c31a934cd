// expect: W0010
// The local variable Kd hides the shader parameter of the same name, so
// the parameter's value is never seen in the body.
surface warn_local_shadows_param(float Kd = 1;)
{
    float Kd = .5;
    Ci = Cs * Kd * diffuse(faceforward(normalize(N), I));
    Oi = Os;
}
