# Components register themselves with one line in their own source file:
#
#   PMLSM_COMPONENT(state_feedback, make_state_feedback, 1)
#
# (nodes/support/component.hpp). pmlsm_component() reads those lines from a component library's
# sources, makes each registered component's standalone executable from a generated main, and
# records it; pmlsm_generate_component_registry(), once every component is added, writes the
# registry the container, the launch agent, the security tool and `container --help` list
# (pmlsm_component_registry: registered_components(), nodes/support/component_registry.hpp).
# Generated code lives in the build tree. A name registered twice stops the configuration,
# naming both files.

set_property(GLOBAL PROPERTY PMLSM_COMPONENTS "")

# pmlsm_write_generated(FILE PIECES...): FILE holds the PIECES joined, rewritten only when it
# changed (so what includes it is not rebuilt at every configuration).
function(pmlsm_write_generated file)
  # ARGV, not ARGN: a piece with a ';' (every C++ statement) stays whole.
  set(text "")
  math(EXPR last "${ARGC} - 1")
  foreach(i RANGE 1 ${last})
    string(APPEND text "${ARGV${i}}")
  endforeach()
  file(WRITE ${file}.in "${text}")
  configure_file(${file}.in ${file} COPYONLY)
endfunction()

# pmlsm_write_table_source(FILE COMMENT c INCLUDE h NAMESPACE ns TYPE T FUNCTION f [PREAMBLE p] ROWS r):
# a source defining `const std::vector<T>& f()`, the table of ROWS (each "      {...},\n").
function(pmlsm_write_table_source file)
  cmake_parse_arguments(PARSE_ARGV 1 ARG "" "COMMENT;INCLUDE;NAMESPACE;TYPE;FUNCTION;PREAMBLE;ROWS" "")
  pmlsm_write_generated(${file}
    "// ${ARG_COMMENT}\n"
    "${ARG_INCLUDE}\n"
    "namespace ${ARG_NAMESPACE} {\n\n"
    "${ARG_PREAMBLE}"
    "const std::vector<${ARG_TYPE}>& ${ARG_FUNCTION}() {\n"
    "  static const std::vector<${ARG_TYPE}> kTable = {\n"
    "${ARG_ROWS}"
    "  };\n"
    "  return kTable;\n"
    "}\n\n"
    "}  // namespace ${ARG_NAMESPACE}\n")
endfunction()

# pmlsm_component(LIBRARY SOURCES... [ORIGIN FILE] [LINK...]): LIBRARY (a static library made from
# SOURCES and linked to pmlsm_node_support, plus any LINK libraries) holds one or more registered
# components; ORIGIN: the file to name for them when SOURCES are generated.
function(pmlsm_component library)
  cmake_parse_arguments(ARG "" "ORIGIN" "SOURCES;LINK" ${ARGN})
  add_library(${library} STATIC ${ARG_SOURCES})
  target_link_libraries(${library} PUBLIC pmlsm_node_support ${ARG_LINK})
  set(found 0)
  foreach(source IN LISTS ARG_SOURCES)
    get_filename_component(path ${source} ABSOLUTE)
    file(STRINGS ${path} lines REGEX "^PMLSM_COMPONENT\\(")
    foreach(line IN LISTS lines)
      if(NOT line MATCHES "^PMLSM_COMPONENT\\(([A-Za-z0-9_]+), *([A-Za-z0-9_]+), *([0-2]|kRunsAlone)\\);?$")
        message(FATAL_ERROR "${path}: '${line}': expected PMLSM_COMPONENT(name, factory, priority), priority 0, 1, 2 or kRunsAlone")
      endif()
      set(name ${CMAKE_MATCH_1})
      set(factory ${CMAKE_MATCH_2})
      set(priority ${CMAKE_MATCH_3})
      if(ARG_ORIGIN)
        set(path ${ARG_ORIGIN})
      endif()
      get_property(registered GLOBAL PROPERTY PMLSM_COMPONENTS)
      foreach(entry IN LISTS registered)
        string(REPLACE "|" ";" fields "${entry}")
        list(GET fields 0 other_name)
        list(GET fields 4 other_path)
        if(other_name STREQUAL name)
          message(FATAL_ERROR "component '${name}' is registered twice: in ${other_path} and in ${path}")
        endif()
      endforeach()
      set_property(GLOBAL APPEND PROPERTY PMLSM_COMPONENTS "${name}|${factory}|${priority}|${library}|${path}")
      # Its program: the component alone in its process.
      set(main ${CMAKE_BINARY_DIR}/generated/components/main_${name}.cpp)
      pmlsm_write_generated(${main}
           "// Generated from ${path}: the component alone in its process.\n"
           "#include \"component.hpp\"\n\n"
           "namespace pmlsm::node {\n"
           "MadeComponent ${factory}(const ComponentContext& context, int argc, char** argv);\n"
           "}\n\n"
           "int main(int argc, char** argv) {\n"
           "  return pmlsm::node::run_standalone(\"${name}\", pmlsm::node::${factory}, argc, argv);\n"
           "}\n")
      add_executable(${name} ${main})
      target_link_libraries(${name} PRIVATE ${library})
      math(EXPR found "${found} + 1")
    endforeach()
  endforeach()
  if(found EQUAL 0)
    message(FATAL_ERROR "${library}: no PMLSM_COMPONENT(name, factory, priority) line in ${ARG_SOURCES}")
  endif()
endfunction()

# The registry of every component added so far: call once, after them.
function(pmlsm_generate_component_registry)
  get_property(registered GLOBAL PROPERTY PMLSM_COMPONENTS)
  set(declarations "")
  set(rows "")
  set(names "")
  set(libraries "")
  foreach(entry IN LISTS registered)
    string(REPLACE "|" ";" fields "${entry}")
    list(GET fields 0 name)
    list(GET fields 1 factory)
    list(GET fields 2 priority)
    list(GET fields 3 library)
    list(GET fields 4 path)
    file(RELATIVE_PATH relative ${PROJECT_SOURCE_DIR} ${path})
    string(APPEND declarations "MadeComponent ${factory}(const ComponentContext& context, int argc, char** argv);\n")
    string(APPEND rows "      {\"${name}\", ${factory}, ${priority}, \"${relative}\"},\n")
    string(APPEND names "    \"${name}\",\n")
    list(APPEND libraries ${library})
  endforeach()
  set(registry ${CMAKE_BINARY_DIR}/generated/components/component_registry.cpp)
  pmlsm_write_table_source(${registry}
    COMMENT "Generated from the PMLSM_COMPONENT lines of the component libraries (cmake/PmlsmComponents.cmake)."
    INCLUDE "#include \"component_registry.hpp\"\n"
    NAMESPACE pmlsm::node TYPE RegisteredComponent FUNCTION registered_components
    PREAMBLE "${declarations}\n" ROWS "${rows}")
  add_library(pmlsm_component_registry STATIC ${registry})
  target_link_libraries(pmlsm_component_registry PUBLIC pmlsm_node_support pmlsm_component_names ${libraries})
  # The names alone, for programs that list them without linking the components (the security
  # tool's identities, the launch agent's allowed programs).
  list(LENGTH registered count)
  set(header ${CMAKE_BINARY_DIR}/generated/components/include/pmlsm/components/registered_names.hpp)
  pmlsm_write_generated(${header}
       "// Generated from the PMLSM_COMPONENT lines of the component libraries (cmake/PmlsmComponents.cmake).\n"
       "#pragma once\n\n"
       "#include <array>\n\n"
       "namespace pmlsm::components {\n\n"
       "/// Every registered component's name (its program's and its container type's), in registration order.\n"
       "inline constexpr std::array<const char*, ${count}> kRegisteredNames = {\n"
       "${names}"
       "};\n\n"
       "}  // namespace pmlsm::components\n")
  add_library(pmlsm_component_names INTERFACE)
  target_include_directories(pmlsm_component_names INTERFACE ${CMAKE_BINARY_DIR}/generated/components/include)
endfunction()
