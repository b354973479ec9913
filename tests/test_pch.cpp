// The translation unit that builds the tests' shared precompiled header
// (HEMM_TEST_PCH in the top-level CMakeLists.txt); it has no code of its own.
