# Sourced by the demo scripts (bash). hemm_display DIR: makes sure the live
# views (--view-png) have an X display to render on: the caller's DISPLAY,
# else an Xvfb of our own (its pid appended to the caller's `pids` array, so
# the caller's exit trap stops it; its display number and log in DIR). The
# views render with software OpenGL (llvmpipe) on one thread, so they do not
# starve the 1 kHz servo and simulation on 2 cores. Returns 1 when there is
# no display and no Xvfb (the runs then leave no pictures).
hemm_display() {
  local dir="$1"
  if [[ -z "${DISPLAY:-}" ]] && command -v Xvfb >/dev/null; then
    rm -f "$dir/xvfb.display"
    Xvfb -displayfd 3 -screen 0 1024x768x24 -nolisten tcp 3>"$dir/xvfb.display" 2>"$dir/xvfb.log" &
    pids+=("$!")
    for _ in $(seq 50); do [[ -s "$dir/xvfb.display" ]] && break; sleep 0.1; done
    [[ -s "$dir/xvfb.display" ]] && export DISPLAY=":$(head -n1 "$dir/xvfb.display")"
  fi
  [[ -n "${DISPLAY:-}" ]] || return 1
  export LIBGL_ALWAYS_SOFTWARE=1 LP_NUM_THREADS=1
}
