// The SVA's K x K median of the output words, as the chip plan describes the stage
// (sva/median/timing.py: median_stage, "median": latency tree(sorting_depth(K K)), II 1; the words
// are sva/median/median.py's definition: element K K / 2 of the sorted window, replicate borders, -1
// (invalid) below every disparity).
//
// Interface (a stage of the lock-step pipeline; every register moves only in a tick, en = 1):
//   in_valid, in_ready, word
//                    one slot of the stream (taken in a tick with in_valid and in_ready):
//                    the frame's words in raster order, then
//                    M W + M flush slots (M = K / 2; word ignored) -- the window centred at
//                    (y, x) is complete when the word at (y + M, x + M) arrives (clamped to
//                    the frame), so the slot of raster index j + M W + M emits centre j;
//   width, height    run-time registers: the frame's W (<= WMAX) and H, held over a frame;
//   out_valid, med   the median of centre j, T ticks after that slot (-1: invalid).
// The stream is skewed by M W + M slots: the stage sees row y + M while it emits row y.
//
// Structure (the cycles come from it):
// - K - 1 row banks of WMAX words (a bank per row above the arriving one, the arriving word
//   written over the oldest row's after its read), a column of K words per slot: the banks'
//   words at x and the arriving word, rows above the frame's first and below its last
//   replaced by the first / last (replicate borders). ONE_PORT = 0: register arrays with a
//   read and a write port, read asynchronously in the slot's tick (in_ready is 1: a slot a
//   tick). ONE_PORT = 1 (sva.sram_ports = "1rw"): each bank has one port, one access a tick
//   (one address, one write enable, the read register): the banks' words at the next column
//   are read in the tick after a slot into the read registers (in_ready rises then), and the
//   slot's tick uses them and writes the arriving word over the oldest row's -- two accesses
//   of the oldest row's bank a slot, so a slot every two ticks at most;
// - a K x K window register shifted one column per slot; the first M slots of a row shift in
//   a copy of the window's last column (the previous row's right border) and keep the new
//   row's first M columns aside; slot M loads [c0 x (M + 1), c1 .. c_{M-1}, c_M];
// - Batcher's odd-even merge sort of the K K words (padded to 2^k, the pairs into the padding
//   left out): k (k + 1) / 2 levels of compare-exchanges, V levels a tick (a register after
//   every V levels, the output register after the last), T = ceil(k (k + 1) / 2 / V); the
//   median is its element K K / 2.
// So centre j leaves T ticks after the slot that completes its window (that slot's tick holds
// the bank read -- or, with one port, the read registers' words --, the window's shift and the
// first V levels): the plan's rule for the network; the M W + M slots of skew are outside it
// (a finding: test_sva_wta_lr_median.py). II: 1 slot a tick with two ports, 2 with one.
module sva_median #(
    parameter int K = 5,        // the window (odd)
    parameter int V = 8,        // compare levels that settle in one tick
    parameter int WB = 9,       // bits of a word (two's complement, -1 invalid)
    parameter int WMAX = 32,    // the widest frame
    parameter int XW = 6,       // bits of a column (> log2 WMAX)
    parameter int YW = 6,       // bits of a row counter (> log2 (H + K))
    parameter bit ONE_PORT = 0  // the row banks: 0 a read and a write port, 1 one
) (
    input  logic              clk,
    input  logic              rst,
    input  logic              en,
    input  logic              in_valid,
    output logic              in_ready,
    input  logic [WB-1:0]     word,
    input  logic [XW-1:0]     width,
    input  logic [YW-1:0]     height,
    output logic              out_valid,
    output logic [WB-1:0]     med
);
  localparam int M = K / 2;
  localparam int NV = K * K;
  localparam int KB = $clog2(NV);              // k: the sort over 2^k
  localparam int NP = 1 << KB;
  localparam int LEVELS = KB * (KB + 1) / 2;   // sorting_depth(K K)
  localparam int T = (LEVELS + V - 1) / V;

  // ---- slot counters: the arriving word's row and column --------------------------------
  logic [XW-1:0] xc;
  logic [YW-1:0] yc;
  logic          slot;
  assign slot = en && in_valid && in_ready;
  logic last_slot;   // the slot of centre (H - 1, W - 1): the frame's last
  assign last_slot = (yc == height + YW'(M)) && (xc == XW'(M - 1));
  always_ff @(posedge clk) begin
    if (rst) begin
      xc <= '0; yc <= '0;
    end else if (slot) begin
      if (last_slot) begin
        xc <= '0; yc <= '0;
      end else if (xc == width - 1'b1) begin
        xc <= '0; yc <= yc + 1'b1;
      end else begin
        xc <= xc + 1'b1;
      end
    end
  end

  // ---- the row banks: bank (row mod (K - 1)) holds a row above the arriving one ----------
  logic [WB-1:0] bank [K-1][WMAX];
  logic [$clog2(K):0] top;   // the bank of the oldest row (y - 2M), rotating per row
  always_ff @(posedge clk) begin
    if (rst) top <= '0;
    else if (slot && xc == width - 1'b1)
      top <= (int'(top) == K - 2) ? '0 : top + 1'b1;
  end
  // ONE_PORT = 1: words[b], bank b's word at column xc, read in the tick after a slot (ready)
  logic [WB-1:0] words [K-1];
  logic          ready;
  always_ff @(posedge clk) begin
    if (rst) ready <= 1'b0;
    else if (en) ready <= ready ? !slot : 1'b1;
  end
  assign in_ready = ONE_PORT ? ready : 1'b1;
  always_ff @(posedge clk) begin
    if (!ONE_PORT) begin   // a read and a write port: the write after the read
      if (slot && yc < height) bank[top][xc] <= word;   // over the oldest row, after its read
    end else begin         // one port a bank: one address (xc), one write enable
      for (int b = 0; b < K - 1; b++) begin
        if (slot && yc < height && b == int'(top)) bank[b][xc] <= word;
        else if (en && !ready) words[b] <= bank[b][xc];
      end
    end
  end
  // col[i]: row yc - 2M + i at column xc (i = K - 1: the arriving word), clamped to the frame
  logic [K-1:0][WB-1:0] raw;   // packed: a column is one word
  logic [K-1:0][WB-1:0] col;
  always_comb begin
    for (int i = 0; i < K - 1; i++) begin
      int b;
      b = (int'(top) + i) % (K - 1);
      raw[i] = ONE_PORT ? words[b] : bank[b][xc];   // two ports: read asynchronously
    end
    raw[K-1] = word;
    for (int i = 0; i < K; i++) begin
      int r, rc;
      r = int'(yc) - 2 * M + i;                   // the row this entry stands for
      rc = (r < 0) ? 0 : (r > int'(height) - 1) ? int'(height) - 1 : r;
      col[i] = raw[i + rc - r];
    end
  end

  // ---- the window register; the network reads the window this slot makes ----------------
  logic [K-1:0][WB-1:0] win [K];    // win[column][row], column K - 1 the newest
  logic [K-1:0][WB-1:0] nwin [K];   // the window after this slot
  logic [K-1:0][WB-1:0] side [M];   // the new row's first M columns
  logic          nvalid;         // the slot emits a centre: slot index >= M W + M
  always_comb begin
    for (int c = 0; c < K; c++) nwin[c] = win[c];
    if (int'(xc) < M) begin       // the previous row's right border: its last column again
      for (int c = 0; c < K - 1; c++) nwin[c] = win[c + 1];
    end else if (int'(xc) == M) begin
      for (int c = 0; c <= M; c++) nwin[c] = (M > 0) ? side[0] : col;
      for (int c = 1; c < M; c++) nwin[M + c] = side[c];
      nwin[K-1] = col;
    end else begin
      for (int c = 0; c < K - 1; c++) nwin[c] = win[c + 1];
      nwin[K-1] = col;
    end
    nvalid = slot && ((int'(yc) > M) || (int'(yc) == M && int'(xc) >= M));
  end
  always_ff @(posedge clk) begin
    if (slot) begin
      for (int c = 0; c < K; c++) win[c] <= nwin[c];
      for (int s = 0; s < M; s++) if (int'(xc) == s) side[s] <= col;
    end
  end

  // ---- Batcher's odd-even merge sort, V levels a tick ----------------------------------
  // level L of the sort: merge size p = 2^a, compare distance 2^b
  function automatic int level_a(input int lv);
    level_a = 0;
    for (int t = 1; t < 32; t = t + 1)
      if (t * (t + 1) / 2 <= lv) level_a = t;
  endfunction
  function automatic int level_b(input int lv);
    int a;
    a = level_a(lv);
    level_b = a - (lv - a * (a + 1) / 2);
  endfunction

  genvar l;
  generate
    for (l = 0; l <= LEVELS; l++) begin : lvl
      localparam bit REG = (l > 0) && (l % V == 0 || l == LEVELS);  // T registers
      logic signed [WB-1:0] c [NP];
      logic signed [WB-1:0] n [NP];
      logic                 cv, nv;
      if (l == 0) begin : leaves
        always_comb begin
          for (int i = 0; i < NP; i++) c[i] = '0;
          for (int cc = 0; cc < K; cc++)
            for (int r = 0; r < K; r++) c[r * K + cc] = nwin[cc][r];
        end
        assign cv = nvalid;
      end else begin : level
        localparam int P = 1 << level_a(l - 1);
        localparam int S = 1 << level_b(l - 1);
        always_comb begin
          c = lvl[l-1].n;
          for (int j = S % P; j < NP - S; j += 2 * S)
            for (int i = 0; i < S; i++)
              if (i + j + S < NP && (i + j) / (2 * P) == (i + j + S) / (2 * P)
                  && i + j + S < NV) begin
                c[i + j] = (lvl[l-1].n[i + j] <= lvl[l-1].n[i + j + S])
                         ? lvl[l-1].n[i + j] : lvl[l-1].n[i + j + S];
                c[i + j + S] = (lvl[l-1].n[i + j] <= lvl[l-1].n[i + j + S])
                             ? lvl[l-1].n[i + j + S] : lvl[l-1].n[i + j];
              end
        end
        assign cv = lvl[l-1].nv;
      end
      if (REG) begin : pipe
        always_ff @(posedge clk) begin
          if (en) n <= c;
          if (rst) nv <= 1'b0; else if (en) nv <= cv;
        end
      end else begin : wire_
        assign n = c; assign nv = cv;
      end
    end
  endgenerate

  assign out_valid = lvl[LEVELS].nv;
  assign med = lvl[LEVELS].n[NV / 2];   // >= -1: the words are
endmodule
