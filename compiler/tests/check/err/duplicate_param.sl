// expect: E0131
// Two shader parameters share the name Kd.
surface duplicate_param(float Kd = 1; float Kd = .5;)
{
    Ci = Cs * Kd * diffuse(faceforward(normalize(N), I));
    Oi = Os;
}
