// expect: E0031
// The file ends inside the shader body: the closing brace of the if
// statement is present but the body's own closing brace is missing.
surface eof_in_block(float Kd = 1;)
{
    normal Nf = faceforward(normalize(N), I);
    if (Kd > 0) {
        Ci = Cs * Kd * diffuse(Nf);
    }
    Oi = Os;
