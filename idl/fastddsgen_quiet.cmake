# Runs fastddsgen with its output (a banner and a line per file) in a log file beside the
# generated code, so the build's screen shows only progress, warnings and errors. On failure
# the log is printed and the build fails.
# -D FASTDDSGEN=... IDL_DIR=... TMP_DIR=... GEN_DIR=... LOG=... IDL_FILES=a.idl|b.idl
string(REPLACE "|" ";" IDL_FILES "${IDL_FILES}")
execute_process(
  COMMAND ${FASTDDSGEN} -cs -replace -I ${IDL_DIR} -t ${TMP_DIR} -d ${GEN_DIR} ${IDL_FILES}
  WORKING_DIRECTORY ${IDL_DIR}
  OUTPUT_FILE ${LOG}
  ERROR_FILE ${LOG}
  RESULT_VARIABLE result)
if(NOT result EQUAL 0)
  file(READ ${LOG} text)
  message(FATAL_ERROR "fastddsgen failed (${result}):\n${text}")
endif()
