# Warnings for the project's own targets: -Wall -Wextra everywhere, errors
# when VKJR2_WERROR is on (CI).
function(vkjr2_set_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wshadow
    -Wnon-virtual-dtor -Wold-style-cast -Wcast-align -Wunused -Woverloaded-virtual
    -Wimplicit-fallthrough
    # Vulkan create-infos are zero-initialized as {VK_STRUCTURE_TYPE_...}.
    -Wno-missing-field-initializers)
  if(VKJR2_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
endfunction()
