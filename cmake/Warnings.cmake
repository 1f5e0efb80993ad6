# Warnings and sanitizers as INTERFACE targets that every project target links.
add_library(displace_warnings INTERFACE)
target_compile_options(displace_warnings INTERFACE -Wall -Wextra -Wpedantic -Wshadow)

add_library(displace_sanitizers INTERFACE)
if(DISPLACE_SANITIZE)
  target_compile_options(displace_sanitizers INTERFACE -fsanitize=address,undefined -fno-omit-frame-pointer)
  target_link_options(displace_sanitizers INTERFACE -fsanitize=address,undefined)
endif()

add_library(displace_options INTERFACE)
target_link_libraries(displace_options INTERFACE displace_warnings displace_sanitizers)
