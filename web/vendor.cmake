# Copies the three.js files the page loads out of node_modules into ASSETS_DIR, flat. The two
# add-ons import the bare specifier 'three'; they get './three.module.js' instead, so the
# page needs no import map (an inline script, which the page's Content-Security-Policy
# forbids). Run as: cmake -DNODE_MODULES=... -DASSETS_DIR=... -P vendor.cmake
file(MAKE_DIRECTORY "${ASSETS_DIR}")
set(three "${NODE_MODULES}/three")
foreach(f three.module.js three.core.js)
  configure_file("${three}/build/${f}" "${ASSETS_DIR}/${f}" COPYONLY)
endforeach()
foreach(f loaders/STLLoader.js controls/OrbitControls.js)
  file(READ "${three}/examples/jsm/${f}" text)
  string(REPLACE "from 'three';" "from './three.module.js';" patched "${text}")
  if(patched STREQUAL text)
    message(FATAL_ERROR "vendor.cmake: ${f} no longer imports from 'three'; update the patch")
  endif()
  get_filename_component(name "${f}" NAME)
  file(WRITE "${ASSETS_DIR}/${name}.tmp" "${patched}")
  file(RENAME "${ASSETS_DIR}/${name}.tmp" "${ASSETS_DIR}/${name}")
endforeach()
configure_file("${three}/LICENSE" "${ASSETS_DIR}/three.LICENSE.txt" COPYONLY)
