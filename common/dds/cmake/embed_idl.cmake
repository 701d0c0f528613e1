# Writes OUTPUT: one C++ initializer per message type, {"Name", R"(flattened IDL)"}, where the
# flattened IDL is Stamp.idl followed by the type's own file with '#include' lines removed.
# Run by the build (cmake -P) whenever an IDL file changes.
#   -DIDL_DIR=... -DNAMES="A;B" -DOUTPUT=...
file(READ ${IDL_DIR}/Stamp.idl stamp_text)
set(out "// Generated from idl/ by common/dds/cmake/embed_idl.cmake. Do not edit.\n")
foreach(name IN LISTS NAMES)
  if(name STREQUAL "Stamp")
    continue()
  endif()
  file(READ ${IDL_DIR}/${name}.idl text)
  string(REGEX REPLACE "#include[^\n]*\n" "" text "${text}")
  string(FIND "${stamp_text}${text}" ")pmlsm_idl\"" clash)
  if(NOT clash EQUAL -1)
    message(FATAL_ERROR "${name}.idl contains the raw-string delimiter")
  endif()
  string(APPEND out "{\"${name}\", R\"pmlsm_idl(${stamp_text}${text})pmlsm_idl\"},\n")
endforeach()
file(WRITE ${OUTPUT}.tmp "${out}")
file(COPY_FILE ${OUTPUT}.tmp ${OUTPUT} ONLY_IF_DIFFERENT)
