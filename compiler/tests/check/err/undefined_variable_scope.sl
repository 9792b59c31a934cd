// expect: E0100
// "shade" is declared inside the if block and is out of scope where it is
// used after the block.
surface undefined_variable_scope(float Kd = 1;)
{
    if (Kd > 0) {
        float shade = Kd * .5;
        Ci = Cs * shade;
    }
    Oi = Os * shade;
}
