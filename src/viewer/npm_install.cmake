# cmake -DNPM=... -DDIR=... -P npm_install.cmake: installs the packages of DIR/package-lock.json.
# npm ci refuses a lock file that lacks the optional per-platform packages of rollup and
# esbuild, which a registry mirror may not carry (seen here); npm install then installs the
# same locked versions.
execute_process(COMMAND "${NPM}" ci --no-audit --no-fund --loglevel=error
                WORKING_DIRECTORY "${DIR}" RESULT_VARIABLE rc OUTPUT_QUIET ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(STATUS "npm ci failed, installing from the lock file with npm install")
  execute_process(COMMAND "${NPM}" install --no-audit --no-fund --loglevel=error
                  WORKING_DIRECTORY "${DIR}" RESULT_VARIABLE rc)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "npm could not install the viewer's packages (npm ci said: ${err})")
  endif()
endif()
