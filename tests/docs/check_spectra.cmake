# Runs the generator and compares its output with the checked-in file (ctest -P script).
execute_process(COMMAND ${STLREFINE} spectrum --markdown
                OUTPUT_VARIABLE generated RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "stlrefine spectrum --markdown failed (exit ${rc})")
endif()
file(READ ${DOC} checked_in)
if(NOT generated STREQUAL checked_in)
  file(WRITE ${CMAKE_CURRENT_BINARY_DIR}/spectra.generated.md "${generated}")
  message(FATAL_ERROR "docs/spectra.md is out of date: `cmake --build build --target docs_spectra` "
                      "rewrites it (what the code prints now: ${CMAKE_CURRENT_BINARY_DIR}/spectra.generated.md)")
endif()
