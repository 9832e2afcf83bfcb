#!/usr/bin/env bash
# test_layers.sh BUILD [ROOT] -- the layering of the sources, from their #include lines: the
# engine's layers (daemon/engine/<layer>/, lowest first: config, beam, forces, integrators,
# estimators, runner, analysis) include only their own layer and those below, always as
# "layer/afm_x.h"; the engine includes no transport, daemon, tool or generated LCM header
# (nor LCM itself); the transports (daemon/transport/) include the engine and each other but
# not the daemon or the tools; the command line both programs share (daemon/cli/) includes
# nothing of the project's but its own; the daemon and the tools include neither each other's files;
# no engine header includes itself back through others (no cycles). One check per file,
# plus the cycle check. ROOT (default: the repository) is where the sources are read, so
# that the check can be tried on a copy. Prints "N passed, N failed".
set -u
ROOT=${2:-$(cd "$(dirname "$0")/.." && pwd)}
cd "$ROOT" || exit 1
LAYERS="config beam forces integrators estimators runner analysis"
pass=0
fail=0

rank_of() { # engine layer name -> 0..5, or -1
    local i=0 l
    for l in $LAYERS; do
        [ "$l" = "$1" ] && { echo $i; return; }
        i=$((i + 1))
    done
    echo -1
}

# why FILE: the reasons (one per line, "line: text") FILE's includes break the rules.
why() {
    local f=$1 dir own=-1 n inc sys
    dir=${f%/*}
    case $f in daemon/engine/*/*) own=$(rank_of "${dir##*/}") ;; esac
    while IFS=: read -r n inc; do
        if [[ $inc =~ ^[[:space:]]*#[[:space:]]*include[[:space:]]*\"([^\"]+)\" ]]; then
            inc=${BASH_REMATCH[1]}
            sys=0
        elif [[ $inc =~ ^[[:space:]]*#[[:space:]]*include[[:space:]]*\<([^\>]+)\> ]]; then
            inc=${BASH_REMATCH[1]}
            sys=1
        else
            continue
        fi
        case $f in
        daemon/engine/*)
            if [ $sys -eq 1 ]; then
                case $inc in lcm/*) echo "$n: <$inc>: the engine does not use LCM (transports do)" ;; esac
                continue
            fi
            local l=${inc%%/*} r
            if [ "$l" = "$inc" ]; then
                echo "$n: \"$inc\": engine includes name their layer (\"layer/afm_x.h\")"
                continue
            fi
            r=$(rank_of "$l")
            if [ "$r" -lt 0 ]; then
                echo "$n: \"$inc\": not an engine layer (the engine includes no transport, daemon or tool)"
            elif [ ! -f "daemon/engine/$inc" ]; then
                echo "$n: \"$inc\": no such engine file"
            elif [ "$r" -gt "$own" ]; then
                echo "$n: \"$inc\": layer $l ($r) is above ${dir##*/} ($own)"
            fi
            ;;
        daemon/transport/*)
            [ $sys -eq 1 ] && continue
            case $inc in
            twind.h) echo "$n: \"$inc\": a transport includes the daemon" ;;
            afmtwin_cmds.h | lcm_tool.h) echo "$n: \"$inc\": a transport includes the tools" ;;
            esac
            ;;
        daemon/cli/*)
            [ $sys -eq 1 ] && continue
            case $inc in cli/*) ;; *) echo "$n: \"$inc\": the shared command line includes only its own files" ;; esac
            ;;
        daemon/*)
            [ $sys -eq 1 ] && continue
            case $inc in afmtwin_cmds.h | lcm_tool.h) echo "$n: \"$inc\": the daemon includes the tools" ;; esac
            ;;
        tools/*)
            [ $sys -eq 1 ] && continue
            case $inc in twind.h) echo "$n: \"$inc\": a tool includes the daemon's own header" ;; esac
            ;;
        esac
    done < <(grep -n '^[[:space:]]*#[[:space:]]*include' "$f")
}

files=$(ls daemon/engine/*/*.[ch] daemon/transport/*.[ch] daemon/cli/*.[ch] daemon/*.[ch] tools/*.[ch] 2>/dev/null)
stray=$(ls daemon/engine/*.[ch] 2>/dev/null)
for f in $stray; do
    echo "FAIL $f: an engine file outside the layer folders"
    fail=$((fail + 1))
done
declare -A okcount=()
for f in $files; do
    w=$(why "$f")
    if [ -n "$w" ]; then
        echo "$w" | sed "s|^|FAIL $f:|"
        fail=$((fail + 1))
    else
        okcount[${f%/*}]=$((${okcount[${f%/*}]:-0} + 1))
        pass=$((pass + 1))
    fi
done
for d in $(printf '%s\n' "${!okcount[@]}" | sort); do
    echo "ok   $d: ${okcount[$d]} files include only what their layer may"
done

# No include cycles among the engine's files (a header reached again from itself).
cyc=$(for f in daemon/engine/*/*.[ch]; do
    grep -o '^[[:space:]]*#[[:space:]]*include[[:space:]]*"[^"]*"' "$f" |
        sed 's/.*"\(.*\)"/\1/' | sed "s|^|${f#daemon/engine/} |"
done | awk '
    { e[$1] = e[$1] " " $2; nodes[$1] = 1 }
    function dfs(u,   i, n, a) {
        if (st[u] == 1) { bad = bad " " u; return }
        if (st[u] == 2) return
        st[u] = 1
        n = split(e[u], a, " ")
        for (i = 1; i <= n; i++) dfs(a[i])
        st[u] = 2
    }
    END { for (u in nodes) dfs(u); print bad }')
if [ -z "${cyc// /}" ]; then
    echo "ok   no include cycles in daemon/engine"
    pass=$((pass + 1))
else
    echo "FAIL include cycle through:$cyc"
    fail=$((fail + 1))
fi
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
