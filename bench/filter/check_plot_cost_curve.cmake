# ctest check of plot_cost_curve (run by `cmake -DTOOL=... -DWORK=... -P`): results made from a known model
# t = c + a n² + b n² m + d n m² must give back its four coefficients, the table and the figure; a broken file
# must give one line naming it and exit 1.
if(NOT TOOL OR NOT WORK)
  message(FATAL_ERROR "usage: cmake -DTOOL=plot_cost_curve -DWORK=dir -P check_plot_cost_curve.cmake")
endif()
file(REMOVE_RECURSE "${WORK}")
file(MAKE_DIRECTORY "${WORK}")

# The model in picoseconds (CMake's math is integer): c 2.1 µs, a 0.29 ns, b 26 ps, d 190 ps; written in ns with
# three decimals, the bench's time unit. Medians (aggregates) are read; the iteration entries must be ignored.
set(entries "")
foreach(m 2 10 24 44)
  foreach(n 99 150 198 249 300 348 399 450 498)
    math(EXPR t_ps "2100000 + 290 * ${n} * ${n} + 26 * ${n} * ${n} * ${m} + 190 * ${n} * ${m} * ${m}")
    math(EXPR whole "${t_ps} / 1000")
    math(EXPR frac "${t_ps} % 1000")
    string(LENGTH "${frac}" len)
    if(len EQUAL 1)
      set(frac "00${frac}")
    elseif(len EQUAL 2)
      set(frac "0${frac}")
    endif()
    string(APPEND entries
      "{\"name\": \"BM_CostVsMapSize/${n}/${m}_median\", \"run_type\": \"aggregate\", \"aggregate_name\": \"median\", "
      "\"rows\": ${n}, \"m\": ${m}, \"cpu_time\": ${whole}.${frac}, \"time_unit\": \"ns\"},\n"
      "{\"name\": \"BM_CostVsMapSize/${n}/${m}\", \"run_type\": \"iteration\", "
      "\"rows\": ${n}, \"m\": ${m}, \"cpu_time\": 1.0, \"time_unit\": \"ns\"},\n")
  endforeach()
endforeach()
file(WRITE "${WORK}/cost.json"
  "{\"context\": {}, \"benchmarks\": [\n${entries}{\"name\": \"BM_Other\", \"cpu_time\": 5.0}\n]}\n")

execute_process(COMMAND "${TOOL}" "${WORK}/cost.json" "${WORK}/out" RESULT_VARIABLE rc OUTPUT_VARIABLE out
                ERROR_VARIABLE err)
if(NOT rc EQUAL 0 AND err MATCHES "gnuplot not found")
  message("plot_cost_curve_fit: skipped, gnuplot not installed")  # the test's SKIP_REGULAR_EXPRESSION
  return()
endif()
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "plot_cost_curve failed (${rc}): ${err}")
endif()
foreach(expected "c = 2.10 µs, a = 0.290 ns, b = 26.0 ps, d = 190.0 ps \\(36 results\\)"
                 "largest model error: 0.0 %" "  498    44 ")
  if(NOT out MATCHES "${expected}")
    message(FATAL_ERROR "plot_cost_curve output lacks '${expected}':\n${out}")
  endif()
endforeach()
foreach(f cost_vs_map_size.dat cost_vs_map_size.svg cost_vs_map_size.png)
  if(NOT EXISTS "${WORK}/out/${f}")
    message(FATAL_ERROR "plot_cost_curve did not write ${f}")
  endif()
endforeach()

# Bad input: one line naming the file, exit 1.
file(WRITE "${WORK}/broken.json" "{\"benchmarks\": [ {\"name\": ")
file(WRITE "${WORK}/none.json" "{\"benchmarks\": [ {\"name\": \"BM_Other\", \"cpu_time\": 1.0} ]}")
foreach(bad broken.json none.json missing.json)
  execute_process(COMMAND "${TOOL}" "${WORK}/${bad}" "${WORK}/out_bad" RESULT_VARIABLE rc OUTPUT_VARIABLE out
                  ERROR_VARIABLE err)
  string(STRIP "${err}" err)
  if(NOT rc EQUAL 1 OR NOT err MATCHES "^plot_cost_curve: [^\n]*${bad}[^\n]*$")
    message(FATAL_ERROR "${bad}: expected one line naming it and exit 1, got exit ${rc}: ${err}")
  endif()
endforeach()
