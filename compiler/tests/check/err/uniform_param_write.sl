// expect: E0110
// Shader parameters are uniform by default; assigning the varying global
// s to Kd is not allowed (declare it "varying float Kd" to do this).
surface uniform_param_write(float Kd = 1;)
{
    Kd = s;
    Ci = Cs * Kd * diffuse(faceforward(normalize(N), I));
    Oi = Os;
}
