/* EXPECT for the plain C test programs: counts failures and prints where (C99). */
#ifndef DN_TEST_EXPECT_H
#define DN_TEST_EXPECT_H

#include <stdio.h>

static int failures = 0;
#define EXPECT(c)                                                      \
  do {                                                                 \
    if (!(c)) {                                                        \
      fprintf(stderr, "%s:%d: expected %s\n", __FILE__, __LINE__, #c); \
      ++failures;                                                      \
    }                                                                  \
  } while (0)

#endif
