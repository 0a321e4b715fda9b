// MATEP_FLATTEN marks the soft path's hot loops [[gnu::flatten]]: every call inside is inlined, so
// the loop keeps its pointers and the contact's values in registers across the contact law.
// Sanitizer builds (MATEP_NO_FLATTEN, set by CMake) leave it out: with the instrumentation inlined
// as well, gcc spent most of an hour on each file that has such a loop. The code is the same.
#pragma once

#if defined(MATEP_NO_FLATTEN)
#define MATEP_FLATTEN
#else
#define MATEP_FLATTEN [[gnu::flatten]]
#endif
