# rosidl_generate_interfaces() makes one library per type support, each compiling one file per
# interface (15 here); every C++ file parses the same Fast-CDR / rosidl headers again. Built as
# one unity source per library, the same code compiles ~4x faster (colcon build of this
# package 77 -> 45 CPU s on a 2-core EPYC VM, 2026-11-27; the rest is rosidl's Python
# generators). Nothing else changes: the same generated sources, symbols and install tree.
#  * rosidl_generator_c's *__description.c files each define the same static names (the type
#    hashes and names of their dependencies), so they stay separate translation units.
#  * the generated C++ files repeat forward declarations that -Wredundant-decls (added by the
#    type support's own flags) reports once they share a unity source: silenced there only.
function(rv_te_unity_build_interfaces)
  get_property(_targets DIRECTORY "${CMAKE_CURRENT_SOURCE_DIR}" PROPERTY BUILDSYSTEM_TARGETS)
  foreach(_t IN LISTS _targets)
    get_target_property(_type ${_t} TYPE)
    if(NOT _type MATCHES "^(SHARED|MODULE|STATIC)_LIBRARY$")
      continue()
    endif()
    set_target_properties(${_t} PROPERTIES UNITY_BUILD ON UNITY_BUILD_BATCH_SIZE 0)
    target_compile_options(${_t} PRIVATE
      $<$<COMPILE_LANG_AND_ID:CXX,GNU,Clang,AppleClang>:-Wno-redundant-decls>)
    get_target_property(_sources ${_t} SOURCES)
    list(FILTER _sources INCLUDE REGEX "__description\\.c$")
    if(_sources)
      set_source_files_properties(${_sources} PROPERTIES SKIP_UNITY_BUILD_INCLUSION ON)
    endif()
  endforeach()
endfunction()
