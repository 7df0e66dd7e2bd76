# Compiler flags, per compiler, as two INTERFACE targets linked privately by the engine (and its
# tests): m3c2_warnings and m3c2_strict_fp. Bit-identical results need IEEE arithmetic exactly
# as written: no FMA contraction (a*b+c rounded once instead of twice) and no fast-math
# reassociation, whatever the compiler's default (GCC contracts across statements, Clang within
# them, MSVC only with /fp:contract, Intel's icx contracts and reassociates by default).

add_library(m3c2_warnings INTERFACE)
add_library(m3c2_strict_fp INTERFACE)

if(MSVC)
  target_compile_options(m3c2_warnings INTERFACE /W4 /permissive-)
  # /fp:precise: no reassociation, and (VS 2022 and later) no contraction without /fp:contract.
  target_compile_options(m3c2_strict_fp INTERFACE /fp:precise)
elseif(CMAKE_CXX_COMPILER_ID STREQUAL "IntelLLVM")
  target_compile_options(m3c2_warnings INTERFACE -Wall -Wextra -Wpedantic)
  target_compile_options(m3c2_strict_fp INTERFACE -fp-model=precise -ffp-contract=off)
elseif(CMAKE_CXX_COMPILER_ID MATCHES "GNU|Clang")  # Clang and AppleClang too
  target_compile_options(m3c2_warnings INTERFACE -Wall -Wextra -Wpedantic)
  target_compile_options(m3c2_strict_fp INTERFACE -ffp-contract=off -fno-fast-math)
else()
  message(WARNING "m3c2: no strict floating-point flags known for ${CMAKE_CXX_COMPILER_ID}: "
                  "check that it neither contracts a*b+c into FMA nor reassociates")
endif()

if(M3C2_SANITIZE)
  if(MSVC)
    add_compile_options(/fsanitize=address)
  else()
    add_compile_options(-fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined)
    add_link_options(-fsanitize=address,undefined)
  endif()
endif()
