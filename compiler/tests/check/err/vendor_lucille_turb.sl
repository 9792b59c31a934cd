// expect: W0012
// lucille's turb(), as its example shaders call it: a colour of fractal noise.
surface matte(float Kd = 1;)
{
    normal Nf = faceforward(normalize(N), I);
    Ci = (0.25 + 0.75 * turb(10.0 * P)) * Kd * diffuse(Nf);
    Oi = Os;
}
