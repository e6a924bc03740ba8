# Embeds the OpenCL sources into the library as string literals, keyed by their path relative
# to kernels/ ("raster.cl", "common/geometry.clh"). The host resolves #include lines itself.
function(penumbra_embed_kernels out_file)
  set(files ${ARGN})
  string(REPLACE ";" "|" file_list "${files}")
  add_custom_command(
    OUTPUT ${out_file}
    COMMAND ${CMAKE_COMMAND} -DOUT=${out_file} -DROOT=${CMAKE_SOURCE_DIR}/kernels
            "-DFILES=${file_list}" -P ${CMAKE_SOURCE_DIR}/cmake/EmbedKernelsScript.cmake
    DEPENDS ${files} ${CMAKE_SOURCE_DIR}/cmake/EmbedKernelsScript.cmake
    COMMENT "Embedding OpenCL kernels" VERBATIM)
endfunction()
