// clang-format off
// Not a kernel: bytes that a naive embedding would mangle. A raw string ends at )" or )cl"
// and R"cl( opens one; a backslash at the end of a line continues it \
// ??= is a trigraph, "quotes" and 'apostrophes', a	tab, UTF-8: Höhle 洞窟,
// a CRLF line above, and no newline at the end.