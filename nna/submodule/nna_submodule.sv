// One NNA submodule, as the chip plan describes it (nna/submodule/timing.py: nna_layers, nna_stages;
// the rules of sim/cycle/rules.py: nna_rows_started_before_input, nna_last_input_row; the
// arithmetic is quant/intconv.py's integer network, the replicate border included).
//
// A pipeline of one or two layer stages (LAYERS), each an nna_layer: its line buffer, its MAC
// array, the bias and, between layers, the requantisation; the last layer's sign bits are the
// descriptor word. Layer 0 takes one pixel a cycle at most (in_valid / in_ready); layer 1's
// line buffer takes layer 0's outputs through the same handshake; the descriptor leaves through
// out_valid / out_ready. Weights, biases, the multiply-shift and the input offset are run-time
// inputs (the chip's configuration registers), so one build serves every network of a shape.
//
// nna_layer, the structure (never delay registers added to meet a number: the cycles come from
// it):
// - line buffer: ROWS rows of the layer's input region, W words of CIN x 8 bits each; the next
//   input word is written in the cycle it is taken, into row slot (its row mod ROWS). It takes
//   one while its row fits beside the rows the next output row reads: row r (r >= ROWS) waits
//   until the output rows done reach min(r + 1 - ROWS + HALF, H) -- the slot it overwrites
//   holds row r - ROWS, which output row y reads until y - HALF > r - ROWS
//   (nna_rows_started_before_input with the whole frame as the tile);
// - window: the K x K words of the current output, a register; one column is read a cycle,
//   one word from each of the 2 HALF + 1 row banks it covers (the plan's line-buffer ports):
//   mid-row output x reads column min(x + HALF, W - 1) in its first MAC cycle (the window
//   shifts by one); a row's first output reads its HALF + 1 distinct columns (column 0 for the
//   replicated border, then 1 .. HALF) one a cycle from the cycle the row may start;
// - MAC array: COUT x P multipliers (P per output channel: the layer's MAC share is COUT P),
//   each channel's P products summed by an adder tree (lg P levels) into its accumulator
//   register, which starts at the bias. Output (x, y) starts once input row
//   min(y + HALF, H - 1) is complete (nna_last_input_row); in its MAC cycle j (0 .. CPP - 1)
//   multiplier p of every channel takes tap t = j P + p of the window (kx-major:
//   t = (kx K + ky) CIN + ci; rows and columns clamped into the frame: the replicate border),
//   so an output takes CPP = ceil(K K CIN / P) = ceil(m / share) cycles (m = K K CIN COUT).
//   A MAC cycle of a row's first output whose last tap's column is not yet read waits for it
//   (never when min(kx of cycle j's last tap, 2 HALF) <= HALF + j for every j: the configs of
//   tests/rtl/test_nna_rtl.py; else each output row starts that many cycles later than the
//   plan's rule says -- a finding, see that file's docstring);
// - the last MAC cycle's sum (accumulator + the tree) goes through the requantisation (per
//   channel (acc * mult) >> shift, clamped to 0..127) or, in the last layer, the sign (acc > 0)
//   in the same cycle: out_valid is high in the output's last MAC cycle; without out_ready the
//   sum waits in the accumulators (out_valid stays high) and the next output starts the cycle
//   after it leaves.
// So an output leaves CPP cycles after it starts, one every CPP cycles when nothing waits: the
// plan's mac_array "II = latency = ceil(m / share)" with requantise / sign "in the MAC array's
// last cycle". Not built: column tiles and row bands (halos), streams of frames.
module nna_layer #(
    parameter int K = 9,        // kernel
    parameter int CIN = 1,      // input channels (layer 0: the pixel)
    parameter int COUT = 32,    // output channels
    parameter int P = 9,        // multipliers per output channel (share = COUT P)
    parameter int ROWS = 10,    // line buffer rows
    parameter int W = 20,       // frame width
    parameter int H = 13,       // frame height
    parameter bit FIRST = 1,    // layer 0: input words are pixels, less the input offset
    parameter bit LAST = 1,     // the last layer: the sign bits, else requantised activations
    parameter int OUT_W = LAST ? COUT : 8 * COUT
) (
    input  logic                          clk,
    input  logic                          rst,
    input  logic                          in_valid,
    output logic                          in_ready,
    input  logic [8*CIN-1:0]              in_data,
    output logic                          out_valid,
    input  logic                          out_ready,
    output logic [OUT_W-1:0]              out_data,
    input  logic [7:0]                    offset,
    input  logic [8*COUT*K*K*CIN-1:0]     weight,   // [co][kx][ky][ci], int8
    input  logic [32*COUT-1:0]            bias,     // int32
    input  logic [16*COUT-1:0]            mult,     // unsigned
    input  logic [16*COUT-1:0]            shift     // unsigned
);
  localparam int HALF = K / 2;
  localparam int TAPS = K * K * CIN;
  localparam int CPP = (TAPS + P - 1) / P;
  localparam int PW = $clog2(CPP + 1);
  localparam int NP = 1 << $clog2(P);        // adder-tree leaves, padded to a power of two

  function automatic int clampi(int v, int lo, int hi);
    clampi = (v < lo) ? lo : (v > hi) ? hi : v;
  endfunction
  function automatic int mini(int a, int b);
    mini = (a < b) ? a : b;
  endfunction

  // ---- line buffer ----------------------------------------------------------------------------
  logic [8*CIN-1:0] mem [ROWS][W];
  logic [15:0] in_row, in_col;      // the next input word's position: in_row rows complete
  logic [15:0] out_x, out_y;        // the next output's position: out_y output rows done
  logic [PW-1:0] phase;             // MAC cycles spent on the current output (CPP: waiting)

  always_comb begin
    in_ready = 1'b0;
    if (int'(in_row) < H)
      in_ready = (int'(in_row) < ROWS)
               || (int'(out_y) >= mini(int'(in_row) + 1 - ROWS + HALF, H));
  end

  always_ff @(posedge clk) begin
    if (rst) begin
      in_row <= '0;
      in_col <= '0;
    end else if (in_valid && in_ready) begin
      mem[int'(in_row) % ROWS][in_col] <= in_data;
      if (int'(in_col) == W - 1) begin
        in_col <= '0;
        in_row <= in_row + 1'b1;
      end else begin
        in_col <= in_col + 1'b1;
      end
    end
  end

  // ---- MAC array: its position and state -------------------------------------------------------
  logic active, starve, go, finishing, fire;
  logic [15:0] ld;                  // a row's first columns read so far (0 .. HALF + 1)
  assign active = int'(out_y) < H;
  assign starve = active && (phase == '0) && !(int'(in_row) > mini(int'(out_y) + HALF, H - 1));
  // the MAC cycle may run: mid-row always; at a row's first output once the column of its last
  // tap (kx-major) is in the window (read this cycle or before)
  assign go = (out_x != '0) || (int'(ld) > HALF)
           || (mini(((int'(phase) + 1) * P - 1) / (K * CIN), 2 * HALF) <= HALF + int'(ld));
  assign finishing = active && !starve && go && (int'(phase) + 1 >= CPP);
  assign out_valid = finishing;
  assign fire = finishing && out_ready;

  // ---- the window: the current output's K columns, one column read from the banks a cycle --
  // win[kx][ky] holds input column clamp(x + kx - HALF) of row clamp(y + ky - HALF). Mid-row,
  // output x's first MAC cycle shifts the window left and reads column min(x + HALF, W - 1)
  // into kx = 2 HALF; a row's first output reads column c = 0 .. HALF in the c-th cycle after
  // the row may start, into kx = 0 .. HALF (c = 0: the replicated border column) or HALF + c.
  // The column read in a cycle is seen by that cycle's taps (a bypass); a MAC cycle j of the
  // row's first output waits (go) until min(kx of its last tap, 2 HALF) <= HALF + c -- never
  // when that holds for c = j in every j (then the row's first output leaves cpp cycles after
  // it starts, as the plan says); else the row's outputs leave that many cycles later.
  logic [8*CIN-1:0] win [K][K];
  logic [8*CIN-1:0] eff [K][K];       // the window as this cycle's taps see it
  logic [8*CIN-1:0] col [K];          // the column read this cycle: one word a row bank
  logic             rd;               // a column is read this cycle
  int               rd_c, rd_lo, rd_hi;
  always_comb begin
    rd = 1'b0;
    rd_c = 0;
    rd_lo = 0;
    rd_hi = 0;
    if (active && !starve) begin
      if (out_x == '0) begin
        if (int'(ld) <= HALF) begin
          rd = 1'b1;
          rd_c = mini(int'(ld), W - 1);
          rd_lo = (ld == '0) ? 0 : HALF + int'(ld);
          rd_hi = HALF + int'(ld);
        end
      end else if (phase == '0) begin
        rd = 1'b1;
        rd_c = mini(int'(out_x) + HALF, W - 1);
        rd_lo = 2 * HALF;
        rd_hi = 2 * HALF;
      end
    end
    for (int ky = 0; ky < K; ky++)
      col[ky] = mem[clampi(int'(out_y) + ky - HALF, 0, H - 1) % ROWS][rd_c];
    for (int kx = 0; kx < K; kx++)
      for (int ky = 0; ky < K; ky++) begin
        eff[kx][ky] = win[kx][ky];
        if (rd && out_x != '0 && kx < 2 * HALF) eff[kx][ky] = win[kx + 1][ky];
        if (rd && kx >= rd_lo && kx <= rd_hi) eff[kx][ky] = col[ky];
      end
  end
  always_ff @(posedge clk) begin
    if (rd) win <= eff;
    if (rst) ld <= '0;
    else if (fire && int'(out_x) == W - 1) ld <= '0;
    else if (rd && out_x == '0) ld <= ld + 1'b1;
  end

  // ---- MAC array: the cycle's P taps, shared by the channels ----------------------------------
  logic signed [9:0] tap_x [P];     // the input of tap j P + p (layer 0: pixel - offset)
  logic [P-1:0]      tap_live;      // the tap exists (the last cycle may have fewer)
  int                tap_t [P];
  genvar gp, gc;
  generate
    for (gp = 0; gp < P; gp++) begin : tap
      int t;
      logic signed [9:0] x;
      always_comb begin
        int ci, ky, kx;
        logic [7:0] v;
        t = int'(phase) * P + gp;
        x = '0;
        ci = 0; ky = 0; kx = 0; v = '0;
        if (t < TAPS) begin                 // t = (kx K + ky) CIN + ci
          ci = t % CIN;
          ky = (t / CIN) % K;
          kx = t / (CIN * K);
          v = eff[kx][ky][8*ci +: 8];
          x = FIRST ? ($signed({2'b00, v}) - $signed({2'b00, offset})) : $signed({2'b00, v});
        end
      end
      assign tap_t[gp] = t;
      assign tap_live[gp] = t < TAPS;
      assign tap_x[gp] = x;
    end
  endgenerate

  // ---- per output channel: P multipliers, an adder tree, the accumulator, requant / sign ------
  // the weight registers as words: wv[co][t] (t = (kx K + ky) CIN + ci)
  logic signed [7:0]  wv    [COUT][TAPS];
  always_comb begin
    for (int c = 0; c < COUT; c++)
      for (int t = 0; t < TAPS; t++) wv[c][t] = $signed(weight[8*(c*TAPS + t) +: 8]);
  end
  logic signed [31:0] acc   [COUT];
  logic signed [31:0] total [COUT];  // the output's sum after this cycle
  // P multipliers per channel (the weight of (channel, tap j P + p) x the tap's input) and
  // each channel's adder tree: lg(NP) levels of two-input adders
  logic signed [31:0] partial [COUT];
  always_comb begin
    for (int c = 0; c < COUT; c++) begin
      logic signed [31:0] s [NP];
      for (int i = 0; i < NP; i++) begin
        logic signed [7:0] w;
        logic signed [9:0] x;
        w = '0;
        x = '0;
        if (i < P && tap_live[i % P]) begin
          w = wv[c][tap_t[i % P]];
          x = tap_x[i % P];
        end
        s[i] = $signed({{24{w[7]}}, w}) * $signed({{22{x[9]}}, x});
      end
      for (int n = NP / 2; n >= 1; n = n / 2)
        for (int i = 0; i < n; i++) s[i] = s[2*i] + s[2*i+1];
      partial[c] = s[0];
    end
  end
  generate
    for (gc = 0; gc < COUT; gc++) begin : chan
      logic signed [31:0] base;
      assign base = (phase == '0) ? $signed(bias[32*gc +: 32]) : acc[gc];
      assign total[gc] = (int'(phase) < CPP) ? base + partial[gc] : acc[gc];
      always_ff @(posedge clk) begin
        if (active && !starve && go && !fire) acc[gc] <= total[gc];
      end
      if (LAST) begin : sign
        assign out_data[gc] = total[gc] > 0;
      end else begin : requant
        logic signed [48:0] pm;
        logic [47:0] q;
        logic [15:0] h;
        assign h = shift[16*gc +: 16];
        assign pm = $signed({{17{total[gc][31]}}, total[gc]})
                  * $signed({33'b0, mult[16*gc +: 16]});
        assign q = (h > 16'd47) ? '0 : (pm[47:0] >> h);
        assign out_data[8*gc +: 8] = pm[48] ? 8'd0 : (q > 48'd127) ? 8'd127 : q[7:0];
      end
    end
  endgenerate

  // ---- the MAC array's position and phase ------------------------------------------------------
  always_ff @(posedge clk) begin
    if (rst) begin
      phase <= '0;
      out_x <= '0;
      out_y <= '0;
    end else if (active && !starve && go) begin
      if (int'(phase) + 1 < CPP) begin
        phase <= phase + 1'b1;
      end else if (fire) begin
        phase <= '0;
        if (int'(out_x) == W - 1) begin
          out_x <= '0;
          out_y <= out_y + 1'b1;
        end else begin
          out_x <= out_x + 1'b1;
        end
      end else begin
        phase <= PW'(CPP);
      end
    end
  end
endmodule

// The submodule: one layer (LAYERS = 1: K0 x K0 x 1 x C1, the descriptor of C1 bits) or a chain
// of two (K0 x K0 x 1 x C1 requantised into K1 x K1 x C1 x C2, the descriptor of C2 bits).
module nna_submodule #(
    parameter int LAYERS = 1,
    parameter int W = 20,
    parameter int H = 13,
    parameter int K0 = 9,
    parameter int C1 = 32,
    parameter int P0 = 9,
    parameter int ROWS0 = 10,
    parameter int K1 = 3,
    parameter int C2 = 8,
    parameter int P1 = 6,
    parameter int ROWS1 = 4,
    parameter int DW = (LAYERS == 1) ? C1 : C2
) (
    input  logic                        clk,
    input  logic                        rst,
    input  logic                        in_valid,
    output logic                        in_ready,
    input  logic [7:0]                  pixel,
    output logic                        out_valid,
    input  logic                        out_ready,
    output logic [DW-1:0]               descriptor,
    input  logic [7:0]                  offset,
    input  logic [8*C1*K0*K0-1:0]       w0,
    input  logic [32*C1-1:0]            b0,
    input  logic [16*C1-1:0]            m0,
    input  logic [16*C1-1:0]            s0,
    input  logic [8*C2*K1*K1*C1-1:0]    w1,
    input  logic [32*C2-1:0]            b1
);
  generate
    if (LAYERS == 1) begin : one
      nna_layer #(.K(K0), .CIN(1), .COUT(C1), .P(P0), .ROWS(ROWS0), .W(W), .H(H), .FIRST(1),
                  .LAST(1)) layer0 (
          .clk, .rst, .in_valid, .in_ready, .in_data(pixel), .out_valid, .out_ready,
          .out_data(descriptor), .offset, .weight(w0), .bias(b0), .mult(m0), .shift(s0));
    end else begin : two
      logic mid_valid, mid_ready;
      logic [8*C1-1:0] mid;
      nna_layer #(.K(K0), .CIN(1), .COUT(C1), .P(P0), .ROWS(ROWS0), .W(W), .H(H), .FIRST(1),
                  .LAST(0)) layer0 (
          .clk, .rst, .in_valid, .in_ready, .in_data(pixel), .out_valid(mid_valid),
          .out_ready(mid_ready), .out_data(mid), .offset, .weight(w0), .bias(b0), .mult(m0),
          .shift(s0));
      nna_layer #(.K(K1), .CIN(C1), .COUT(C2), .P(P1), .ROWS(ROWS1), .W(W), .H(H), .FIRST(0),
                  .LAST(1)) layer1 (
          .clk, .rst, .in_valid(mid_valid), .in_ready(mid_ready), .in_data(mid), .out_valid,
          .out_ready, .out_data(descriptor), .offset, .weight(w1), .bias(b1),
          .mult({16*C2{1'b0}}), .shift({16*C2{1'b0}}));
    end
  endgenerate
endmodule
