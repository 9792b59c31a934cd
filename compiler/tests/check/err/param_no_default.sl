// expect: E0120
// Every shader parameter needs a default value; Kd has none.
surface param_no_default(float Ka = 1; float Kd;)
{
    normal Nf = faceforward(normalize(N), I);
    Ci = Cs * (Ka * ambient() + Kd * diffuse(Nf));
    Oi = Os;
}
