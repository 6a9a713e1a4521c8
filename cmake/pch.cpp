// The unit that compiles photomill's precompiled header (CMakeLists.txt, PHOTOMILL_PCH).
