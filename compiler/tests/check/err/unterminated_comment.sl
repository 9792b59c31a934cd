// expect: E0022
// The block comment opened after the shader is never closed.
surface unterminated_comment()
{
    Ci = Cs;
    Oi = Os;
}

/* This comment runs to the end of the file
   because its closing star-slash is missing.
