// expect: E0100
// "kd" is never declared (the parameter is spelled "Kd"; names are
// case-sensitive).
surface undefined_variable(float Kd = 1;)
{
    normal Nf = faceforward(normalize(N), I);
    Ci = Cs * Kd * diffuse(Nf);
    Oi = Os * kd;
}
