#!/bin/sh
# MAVProxy on `parapet pil --gcs udp:127.0.0.1:PORT`: `param fetch` and `wp list` complete.
# usage: gcs_mavproxy.sh VENV_BIN PORT LOGDIR
set -u
"$1/mavproxy.py" --master "udpin:127.0.0.1:$2" --daemon --non-interactive --state-basedir "$3" \
  --cmd "set heartbeat 1; param fetch; wp list" >"$3/mavproxy.out" 2>&1 &
pid=$!
sleep 25
kill "$pid" 2>/dev/null
cat "$3/mavproxy.out"
grep -q "Received [0-9]* parameters" "$3/mavproxy.out" || { echo "FAIL: param fetch did not complete"; exit 1; }
grep -qi "Requesting [0-9]* waypoints\|Saved [0-9]* waypoints\|Loaded [0-9]* waypoints" "$3/mavproxy.out" || { echo "FAIL: wp list did not complete"; exit 1; }
echo PASS
