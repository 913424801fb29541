// Owner of the test executables' precompiled header (tests/CMakeLists.txt); no code.
