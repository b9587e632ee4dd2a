# Warnings for the project's own targets, treated as errors (SINEW_WERROR, on by default).
# Third-party headers are included as SYSTEM so their warnings never break the build.
option(SINEW_WERROR "Treat warnings in Sinew's own code as errors" ON)

add_library(sinew_warnings INTERFACE)
target_compile_options(sinew_warnings INTERFACE
  -Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor -Wcast-align -Woverloaded-virtual
  -Wnull-dereference -Wimplicit-fallthrough -Wno-unused-parameter
  $<$<BOOL:${SINEW_WERROR}>:-Werror>)
