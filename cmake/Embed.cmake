# gvd_embed_text(OUTPUT NAMESPACE FILE...): a build step that writes the header OUTPUT holding
# the FILEs as string constants in NAMESPACE (cmake/EmbedText.cmake says how they are named),
# rewritten whenever one of them changes.
function(gvd_embed_text output namespace)
  set(files ${ARGN})
  list(JOIN files "|" inputs)
  add_custom_command(
    OUTPUT ${output}
    COMMAND ${CMAKE_COMMAND} -DOUTPUT=${output} -DNAMESPACE=${namespace} "-DINPUTS=${inputs}"
            -P ${PROJECT_SOURCE_DIR}/cmake/EmbedText.cmake
    DEPENDS ${files} ${PROJECT_SOURCE_DIR}/cmake/EmbedText.cmake
    COMMENT "Embedding ${namespace}"
    VERBATIM)
endfunction()
