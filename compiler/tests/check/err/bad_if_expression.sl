// expect: E0006
// The #if expression is incomplete: the + operator has no right operand.
#if 1 +
#define BRIGHT 2
#endif

surface bad_if_expression()
{
    Ci = Cs;
    Oi = Os;
}
