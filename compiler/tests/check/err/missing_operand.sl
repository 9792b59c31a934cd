// expect: E0030
// Syntax error: the binary + has no right operand.
surface missing_operand(float Ka = 1;)
{
    Ci = Cs * (Ka * ambient() + );
    Oi = Os;
}
