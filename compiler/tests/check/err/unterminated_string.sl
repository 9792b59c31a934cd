// expect: E0021
// The string literal passed to printf has no closing quote.
surface unterminated_string()
{
    printf("shading point %p\n, P);
    Ci = Cs;
    Oi = Os;
}
