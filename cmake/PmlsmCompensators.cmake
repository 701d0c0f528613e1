# Compensators added in their own folders: compensators/<name>/<name>.hpp holds the law's class and
# one line,
#
#   PMLSM_COMPENSATOR(spring_force_feedback, SpringForceFeedback);
#
# (pmlsm/sim/compensator_law.hpp). pmlsm_discover_compensators() finds every such folder and makes
# pmlsm_parameter_sections, the table of their parameter sections every reader of a system file
# reads (registered_parameter_sections()); pmlsm_compensator_components(), in the nodes, makes
# each one's component (a registered PMLSM_COMPONENT, so its program, its container type and its
# place in the agent's and the security policy's lists) from a generated source. Nothing else names
# them. Generated code lives in the build tree.

set_property(GLOBAL PROPERTY PMLSM_COMPENSATOR_LAWS "")
set_property(GLOBAL PROPERTY PMLSM_LIBRARY_SECTIONS "")

# pmlsm_parameter_section(AT key.path TYPE Params HEADER path LIBRARY target [LIVE_AT node]): a
# library's Params joined to the system file's table as the section at AT (before the compensators'
# sections), declared in HEADER (from the calling folder; included as from LIBRARY's include
# directory), its live entries taken by LIVE_AT.
function(pmlsm_parameter_section)
  cmake_parse_arguments(ARG "" "AT;TYPE;HEADER;LIBRARY;LIVE_AT" "" ${ARGN})
  foreach(required AT TYPE HEADER LIBRARY)
    if(NOT ARG_${required})
      message(FATAL_ERROR "pmlsm_parameter_section: ${required} is required")
    endif()
  endforeach()
  set(header ${CMAKE_CURRENT_SOURCE_DIR}/${ARG_HEADER})
  if(NOT EXISTS ${header})
    message(FATAL_ERROR "pmlsm_parameter_section(${ARG_AT}): no ${header}")
  endif()
  if(NOT ARG_LIVE_AT)
    set(ARG_LIVE_AT "")
  endif()
  set_property(GLOBAL APPEND PROPERTY PMLSM_LIBRARY_SECTIONS "${ARG_AT}|${ARG_TYPE}|${header}|${ARG_LIBRARY}|${ARG_LIVE_AT}")
endfunction()

function(pmlsm_discover_compensators)
  file(GLOB children LIST_DIRECTORIES true CONFIGURE_DEPENDS RELATIVE ${CMAKE_CURRENT_SOURCE_DIR} ${CMAKE_CURRENT_SOURCE_DIR}/*)
  list(SORT children)
  set(includes "")
  set(rows "")
  set(libraries "")
  get_property(library_sections GLOBAL PROPERTY PMLSM_LIBRARY_SECTIONS)
  foreach(entry IN LISTS library_sections)
    string(REPLACE "|" ";" fields "${entry}")
    list(GET fields 0 at)
    list(GET fields 1 type)
    list(GET fields 2 header)
    list(GET fields 3 library)
    list(LENGTH fields field_count)
    set(live_at "nullptr")
    if(field_count GREATER 4)
      list(GET fields 4 live_name)
      if(live_name)
        set(live_at "\"${live_name}\"")
      endif()
    endif()
    get_target_property(include_dirs ${library} INTERFACE_INCLUDE_DIRECTORIES)
    set(include_path "")
    foreach(dir IN LISTS include_dirs)
      file(RELATIVE_PATH candidate ${dir} ${header})
      if(NOT candidate MATCHES "^\\.\\.")
        set(include_path ${candidate})
      endif()
    endforeach()
    if(NOT include_path)
      message(FATAL_ERROR "pmlsm_parameter_section(${at}): ${header} is not under ${library}'s include directories")
    endif()
    file(RELATIVE_PATH relative ${PROJECT_SOURCE_DIR} ${header})
    string(APPEND includes "#include \"${include_path}\"\n")
    string(APPEND rows "      parameter_section<${type}>(\"${at}\", ${live_at}, \"${relative}\"),\n")
    list(APPEND libraries ${library})
  endforeach()
  foreach(name IN LISTS children)
    set(folder ${CMAKE_CURRENT_SOURCE_DIR}/${name})
    if(NOT IS_DIRECTORY ${folder})
      continue()
    endif()
    set(header ${folder}/${name}.hpp)
    if(NOT EXISTS ${header})
      message(FATAL_ERROR "${folder}: a compensator's folder holds ${name}.hpp (the law and its PMLSM_COMPENSATOR line)")
    endif()
    # Every file of the folder: a change to any of them configures again.
    file(GLOB_RECURSE folder_files ${folder}/*)
    set_property(DIRECTORY APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS ${folder_files})
    file(STRINGS ${header} lines REGEX "^PMLSM_COMPENSATOR\\(")
    list(LENGTH lines count)
    if(NOT count EQUAL 1)
      message(FATAL_ERROR "${header}: expected one PMLSM_COMPENSATOR(${name}, Class) line, found ${count}")
    endif()
    list(GET lines 0 line)
    if(NOT line MATCHES "^PMLSM_COMPENSATOR\\(([A-Za-z0-9_]+), *([A-Za-z_][A-Za-z0-9_:]*)\\);?$")
      message(FATAL_ERROR "${header}: '${line}': expected PMLSM_COMPENSATOR(${name}, Class)")
    endif()
    if(NOT CMAKE_MATCH_1 STREQUAL name)
      message(FATAL_ERROR "${header}: registers '${CMAKE_MATCH_1}' in the folder '${name}': a compensator is named as its folder")
    endif()
    set(law ${CMAKE_MATCH_2})
    file(RELATIVE_PATH relative ${PROJECT_SOURCE_DIR} ${header})
    string(APPEND includes "#include \"${name}/${name}.hpp\"\n")
    string(APPEND rows "      parameter_section<${law}::Params>(\"compensator.${name}\", \"${name}\", \"${relative}\"),\n")
    set_property(GLOBAL APPEND PROPERTY PMLSM_COMPENSATOR_LAWS "${name}|${law}|${header}")
  endforeach()
  set(table ${CMAKE_BINARY_DIR}/generated/compensators/parameter_sections.cpp)
  pmlsm_write_table_source(${table}
    COMMENT "Generated from the PMLSM_COMPENSATOR lines of compensators/*/ (cmake/PmlsmCompensators.cmake)."
    INCLUDE "#include \"pmlsm/util/parameter_section.hpp\"\n${includes}"
    NAMESPACE pmlsm TYPE ParameterSection FUNCTION registered_parameter_sections ROWS "${rows}")
  add_library(pmlsm_parameter_sections STATIC ${table})
  target_include_directories(pmlsm_parameter_sections PUBLIC ${CMAKE_CURRENT_SOURCE_DIR})
  target_link_libraries(pmlsm_parameter_sections PUBLIC pmlsm_sim ${libraries})
  set_target_properties(pmlsm_parameter_sections PROPERTIES POSITION_INDEPENDENT_CODE ON)
endfunction()

# Each discovered law's component: a generated source with its PMLSM_COMPONENT line (priority 1:
# a compensator feeds the next tick), wrapping the law in LawCompensator.
function(pmlsm_compensator_components)
  get_property(laws GLOBAL PROPERTY PMLSM_COMPENSATOR_LAWS)
  foreach(entry IN LISTS laws)
    string(REPLACE "|" ";" fields "${entry}")
    list(GET fields 0 name)
    list(GET fields 1 law)
    list(GET fields 2 header)
    file(RELATIVE_PATH relative ${PROJECT_SOURCE_DIR} ${header})
    set(source ${CMAKE_BINARY_DIR}/generated/compensators/component_${name}.cpp)
    pmlsm_write_generated(${source}
         "// Generated from ${relative}: its law as a component (cmake/PmlsmCompensators.cmake).\n"
         "#include \"${name}/${name}.hpp\"\n"
         "#include \"law_compensator.hpp\"\n\n"
         "namespace pmlsm::node {\n\n"
         "PMLSM_COMPONENT(${name}, make_${name}, 1);\n\n"
         "MadeComponent make_${name}(const ComponentContext& context, int argc, char** argv) {\n"
         "  return make_law_compensator<${law}>(\"${name}\", context, argc, argv);\n"
         "}\n\n"
         "}  // namespace pmlsm::node\n")
    pmlsm_component(pmlsm_component_${name} SOURCES ${source} ORIGIN ${header} LINK pmlsm_parameter_sections)
    target_include_directories(pmlsm_component_${name} PRIVATE ${CMAKE_CURRENT_SOURCE_DIR})
  endforeach()
endfunction()

# pmlsm_compensator_names(VAR): the discovered compensators' names (their programs), for targets
# that run every one of them.
function(pmlsm_compensator_names var)
  get_property(laws GLOBAL PROPERTY PMLSM_COMPENSATOR_LAWS)
  set(names "")
  foreach(entry IN LISTS laws)
    string(REPLACE "|" ";" fields "${entry}")
    list(GET fields 0 name)
    list(APPEND names ${name})
  endforeach()
  set(${var} ${names} PARENT_SCOPE)
endfunction()
