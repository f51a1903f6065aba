# gvd_proto_library(NAME ROOT proto...): compiles .proto files under ROOT (relative paths kept)
# into two static libraries: NAME, the messages (protobuf only, what the application core
# links), and NAME_grpc, the gRPC service code over them (what the gRPC transport and the
# clients link).
function(gvd_proto_library name root)
  get_target_property(grpc_plugin gRPC::grpc_cpp_plugin LOCATION)
  set(gen ${CMAKE_CURRENT_BINARY_DIR}/gen)
  file(MAKE_DIRECTORY ${gen})
  set(messages)
  set(services)
  foreach(proto ${ARGN})
    file(RELATIVE_PATH rel ${root} ${proto})
    string(REGEX REPLACE "\\.proto$" "" base ${rel})
    set(message_outs ${gen}/${base}.pb.cc ${gen}/${base}.pb.h)
    set(service_outs ${gen}/${base}.grpc.pb.cc ${gen}/${base}.grpc.pb.h)
    add_custom_command(
      OUTPUT ${message_outs} ${service_outs}
      COMMAND protobuf::protoc --proto_path=${root} --cpp_out=${gen} --grpc_out=${gen}
              --plugin=protoc-gen-grpc=${grpc_plugin} ${proto}
      DEPENDS ${proto} protobuf::protoc
      COMMENT "protoc ${rel}")
    list(APPEND messages ${message_outs})
    list(APPEND services ${service_outs})
  endforeach()
  add_library(${name} STATIC ${messages})
  target_include_directories(${name} PUBLIC $<BUILD_INTERFACE:${gen}> $<INSTALL_INTERFACE:include>)
  target_link_libraries(${name} PUBLIC protobuf::libprotobuf)
  add_library(${name}_grpc STATIC ${services})
  target_link_libraries(${name}_grpc PUBLIC ${name} $<BUILD_INTERFACE:gvd_grpc_link_grpc++>
    $<INSTALL_INTERFACE:gRPC::grpc++>)
endfunction()
