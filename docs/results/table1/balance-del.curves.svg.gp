# balance-del: redraw with `gnuplot /work/main/docs/results/table1/balance-del.curves.svg.gp`
set terminal svg size 760,480 dynamic font "sans,11"
set output "/work/main/docs/results/table1/balance-del.curves.svg"
set termoption noenhanced
set style fill transparent solid 0.18 noborder
set grid
set xlabel "episode"
set ylabel "evaluation cost"
set xtics 1
set key outside right top vertical box font ",9" samplen 2 spacing 0.9
set multiplot layout 1,1 title "sweep balance-del: evaluation cost per episode, median and quartiles over trials (n = trials)"
set title "cartpole-balance, angle cost, k = 1"
plot "/work/main/docs/results/table1/balance-del.curves.svg.dat" index 0 using 1:2:4 with filledcurves lc rgb "#ff9da7" notitle, \
     "/work/main/docs/results/table1/balance-del.curves.svg.dat" index 0 using 1:3 with linespoints lc rgb "#ff9da7" lw 2 pt 7 ps 0.5 title "DEL (n=10)", \
     "/work/main/docs/results/table1/balance-del.curves.svg.dat" index 1 using 1:2:4 with filledcurves lc rgb "#e15759" notitle, \
     "/work/main/docs/results/table1/balance-del.curves.svg.dat" index 1 using 1:3 with linespoints lc rgb "#e15759" lw 2 pt 7 ps 0.5 title "RP (n=10)", \
     "/work/main/docs/results/table1/balance-del.curves.svg.dat" index 2 using 1:2:4 with filledcurves lc rgb "#76b7b2" notitle, \
     "/work/main/docs/results/table1/balance-del.curves.svg.dat" index 2 using 1:3 with linespoints lc rgb "#76b7b2" lw 2 pt 7 ps 0.5 title "LR (n=10)", \
     15 with lines dt 2 lw 1.5 lc rgb "#555555" title "success threshold 15"
unset multiplot
