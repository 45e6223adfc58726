# rpyfmm_set_warnings(<target>): the project's warning set, applied per target
# (never globally, so consumers of the installed package are unaffected).
function(rpyfmm_set_warnings target)
  target_compile_options(${target} PRIVATE
    $<$<COMPILE_LANGUAGE:CXX>:-Wall -Wextra -Wpedantic -Wshadow -Wno-unknown-pragmas>)
  if(RPYFMM_NATIVE)
    target_compile_options(${target} PRIVATE $<$<COMPILE_LANGUAGE:CXX>:-march=native>)
  endif()
endfunction()
