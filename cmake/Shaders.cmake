# displace_shader(SYMBOL FILE STAGE [DEFINE...]): shaders/FILE.glsl of the calling directory, compiled
# by glslangValidator at build time with the defines, into the C header spirv/SYMBOL.h (the array
# spirv_SYMBOL) of the calling directory's build tree (never committed), which its library embeds. The
# caller sets DISPLACE_SHADER_INCLUDES (the headers its shaders include) first; the outputs are
# appended to DISPLACE_SHADER_HEADERS in the caller's scope.
function(displace_shader symbol file stage)
  set(output ${CMAKE_CURRENT_BINARY_DIR}/spirv/${symbol}.h)
  set(defines)
  foreach(define ${ARGN})
    list(APPEND defines -D${define})
  endforeach()
  add_custom_command(
    OUTPUT ${output}
    COMMAND ${CMAKE_COMMAND} -E make_directory ${CMAKE_CURRENT_BINARY_DIR}/spirv
    COMMAND ${GLSLANG_VALIDATOR} --quiet -V --target-env vulkan1.2 -S ${stage} --vn spirv_${symbol} ${defines}
            -I${CMAKE_CURRENT_SOURCE_DIR}/shaders -o ${output} ${CMAKE_CURRENT_SOURCE_DIR}/shaders/${file}.glsl
    DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/shaders/${file}.glsl ${DISPLACE_SHADER_INCLUDES}
    COMMENT "glslang: ${symbol}"
    VERBATIM)
  set(DISPLACE_SHADER_HEADERS ${DISPLACE_SHADER_HEADERS} ${output} PARENT_SCOPE)
endfunction()
