# `cmake --install BUILD_DIR --prefix PREFIX`, then: the binaries, both man pages, the
# licence, the sysusers.d entry, and the systemd unit whose ExecStart names PREFIX's daemon.
file(REMOVE_RECURSE ${PREFIX})
execute_process(COMMAND ${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${PREFIX}
                RESULT_VARIABLE result OUTPUT_VARIABLE output ERROR_VARIABLE output)
if(NOT result EQUAL 0)
  message(FATAL_ERROR "cmake --install failed (${result}):\n${output}")
endif()
foreach(file
    bin/stlrefine
    bin/stlrefined
    share/man/man1/stlrefine.1
    share/man/man8/stlrefined.8
    share/doc/stlrefine/LICENSE
    lib/sysusers.d/stlrefine.conf
    lib/systemd/system/stlrefined.service)
  if(NOT EXISTS ${PREFIX}/${file})
    message(FATAL_ERROR "not installed: ${file}\n${output}")
  endif()
endforeach()
file(STRINGS ${PREFIX}/lib/systemd/system/stlrefined.service exec REGEX "^ExecStart=")
if(NOT exec MATCHES "^ExecStart=${PREFIX}/bin/stlrefined ")
  message(FATAL_ERROR "the unit does not start the installed daemon: ${exec}")
endif()
# systemd's own check of the installed unit (syntax, the ExecStart binary, the man page
# Documentation= names), where systemd is installed.
find_program(SYSTEMD_ANALYZE systemd-analyze)
if(SYSTEMD_ANALYZE)
  execute_process(
    COMMAND ${CMAKE_COMMAND} -E env MANPATH=${PREFIX}/share/man
            ${SYSTEMD_ANALYZE} verify ${PREFIX}/lib/systemd/system/stlrefined.service
    RESULT_VARIABLE result OUTPUT_VARIABLE output ERROR_VARIABLE output)
  if(NOT result EQUAL 0)
    message(FATAL_ERROR "systemd-analyze verify failed (${result}):\n${output}")
  endif()
else()
  message(STATUS "no systemd-analyze: the unit's syntax is not verified")
endif()
file(REMOVE_RECURSE ${PREFIX})
